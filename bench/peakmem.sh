#!/usr/bin/env bash
# bench/peakmem.sh OUT CMD... - stand-in for `/usr/bin/time -f '%e %M' -o OUT CMD...`
# where GNU time (Debian package `time`) is missing: runs CMD, polls its VmHWM (the
# kernel's peak resident set size) in /proc every 10 ms, and writes "SECONDS PEAK_KIB"
# to OUT. Growth in the last 10 ms before CMD exits can be missed; GNU time cannot.
# Exit status: CMD's.
set -u
out=$1; shift
t0=$(date +%s.%N)
"$@" &
pid=$!
peak=0
# An exited child stays a zombie (state Z, no VmHWM) until `wait`: stop polling then.
while :; do
  read -r st v < <(awk '/^State:/ { s = $2 } /^VmHWM:/ { h = $2 } END { print s, h }' \
                   "/proc/$pid/status" 2>/dev/null) || break
  [ -n "$st" ] && [ "$st" != Z ] || break
  if [ -n "$v" ] && [ "$v" -gt "$peak" ]; then peak=$v; fi
  sleep 0.01
done
wait "$pid"; rc=$?
t1=$(date +%s.%N)
awk -v a="$t0" -v b="$t1" -v p="$peak" 'BEGIN { printf "%.2f %d\n", b - a, p }' > "$out"
exit "$rc"
