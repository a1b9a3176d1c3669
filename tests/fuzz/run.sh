#!/usr/bin/env bash
# tests/fuzz/run.sh - run every libFuzzer harness in BINDIR for SECONDS each
# (default 30), one after the other, and print one summary line per harness.
#
#   tests/fuzz/run.sh BINDIR [SECONDS]        (`make fuzz FUZZ_SECONDS=N` calls this)
#
# Each harness NAME starts from its seeds in tests/fuzz/corpus/NAME/ (and the
# dictionary tests/fuzz/corpus/NAME.dict if there is one), copied into the
# scratch corpus build/fuzz/corpus/NAME/. That corpus is kept between runs, so
# coverage accumulates; `rm -rf build/fuzz/corpus` starts again from the seeds.
# Nothing is written into the repository. Crashes, sanitizer reports, leaks,
# timeouts and out-of-memory inputs are saved under build/fuzz/artifacts/NAME/
# and the reproducer is printed; the full log is build/fuzz/logs/NAME.log.
#
# Environment: FUZZ_ONLY (substring of the harness names to run),
# FUZZ_TIMEOUT (seconds one input may take, default 10), FUZZ_RSS_MB (default 2048).
# Exit status: 0 no finding, 1 at least one harness found a problem,
# 2 usage, 4 no harness or a harness that cannot be run.
set -u

usage() { echo "usage: tests/fuzz/run.sh BINDIR [SECONDS]" >&2; exit 2; }
[ $# -ge 1 ] && [ $# -le 2 ] || usage
bindir=$1
[ -d "$bindir" ] && bindir=$(cd "$bindir" && pwd)   # BINDIR is relative to the caller
cd "$(dirname "$0")/../.." || exit 4
secs=${2:-30}
[[ "$secs" =~ ^[1-9][0-9]*$ ]] || { echo "run.sh: SECONDS must be a positive integer, got '$secs'" >&2; usage; }
timeout_s=${FUZZ_TIMEOUT:-10}
rss_mb=${FUZZ_RSS_MB:-2048}

seeds_root=tests/fuzz/corpus
work=build/fuzz
mkdir -p "$work/corpus" "$work/artifacts" "$work/logs" || exit 4

# Largest input libFuzzer may make, per harness: a little above the largest seed,
# enough room to grow (the container harness also repairs inputs up to 1 MiB).
max_len_of() {
  case $1 in
    fuzz_container) echo 4096 ;;
    fuzz_script) echo 2048 ;;
    fuzz_gltf) echo 8192 ;;
    *) echo 4096 ;;
  esac
}

# UBSan reports must stop the run so libFuzzer saves the input (the library is
# built with recoverable UBSan); leaks count as findings.
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-halt_on_error=1:print_stacktrace=1}
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=0}

# stat KEY LOG: the value of libFuzzer's "stat::KEY: N" line.
stat() { sed -n "s/^stat::$1: *//p" "$2" | tail -1; }

found=0 ran=0 broken=0
shopt -s nullglob
for bin in "$bindir"/fuzz_*; do
  name=$(basename "$bin")
  [[ "$name" == *.* ]] && continue          # .d dependency files beside the binaries
  [ -f "$bin" ] && [ -x "$bin" ] || continue
  [ -n "${FUZZ_ONLY:-}" ] && [[ "$name" != *"$FUZZ_ONLY"* ]] && continue
  ran=$((ran + 1))
  corpus=$work/corpus/$name
  artifacts=$work/artifacts/$name
  log=$work/logs/$name.log
  mkdir -p "$corpus" "$artifacts"
  nseeds=0
  if [ -d "$seeds_root/$name" ]; then
    for s in "$seeds_root/$name"/*; do
      [ -f "$s" ] || continue
      cp -f "$s" "$corpus/" && nseeds=$((nseeds + 1))
    done
  fi
  [ "$nseeds" -eq 0 ] && echo "run.sh: warning: no seeds in $seeds_root/$name/, starting from an empty corpus" >&2
  before=$(find "$corpus" -type f | wc -l)
  dict=()
  [ -f "$seeds_root/$name.dict" ] && dict=(-dict="$seeds_root/$name.dict")
  # Artifacts from an earlier run are not findings of this one.
  marker=$work/logs/.$name.start
  : >"$marker"

  t0=$(date +%s.%N)
  "$bin" -max_total_time="$secs" -max_len="$(max_len_of "$name")" -timeout="$timeout_s" \
    -rss_limit_mb="$rss_mb" -print_final_stats=1 -artifact_prefix="$artifacts/" \
    "${dict[@]}" "$corpus" >"$log" 2>&1
  rc=$?
  t1=$(date +%s.%N)
  wall=$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.1f", b - a }')

  runs=$(stat number_of_executed_units "$log")
  rate=$(stat average_exec_per_sec "$log")
  rss=$(stat peak_rss_mb "$log")
  cov=$(grep -Eo 'cov: [0-9]+ ft: [0-9]+' "$log" | tail -1)
  after=$(find "$corpus" -type f | wc -l)
  line=$(printf '%-16s runs %9s in %5ss (%s/s), %s, corpus %d (+%d), rss %s MB' \
    "$name" "${runs:-?}" "$wall" "${rate:-?}" "${cov:-cov: ?}" "$after" $((after - before)) "${rss:-?}")

  repro=$(find "$artifacts" -type f -newer "$marker" | sort | head -1)
  rm -f "$marker"
  if [ "$rc" -eq 0 ] && [ -z "$repro" ]; then
    echo "ok    $line"
    continue
  fi
  if [ -z "$repro" ] && [ -z "$runs" ] && ! grep -q 'ERROR: \|SUMMARY: \|runtime error' "$log"; then
    broken=1
    echo "FAIL  $name: exit $rc before fuzzing started (log: $log)"
    tail -5 "$log" | sed 's/^/      /'
    continue
  fi
  found=1
  what=$(grep -m1 -Eo 'SUMMARY: [A-Za-z]+: [^ ]+|ERROR: libFuzzer: [a-z-]+|runtime error: .*' "$log")
  echo "FOUND $line"
  echo "      ${what:-exit $rc} (log: $log)"
  if [ -n "$repro" ]; then
    echo "      reproducer: $repro"
    echo "      replay:     $bin $repro"
  fi
done

if [ "$ran" -eq 0 ]; then
  echo "run.sh: no harness (fuzz_*) in $bindir" >&2
  exit 4
fi
[ "$found" -ne 0 ] && exit 1
[ "$broken" -ne 0 ] && exit 4
exit 0
