#!/usr/bin/env bash
# tests/run.sh - run the unit tests (cmocka binaries given as arguments) and the
# CLI tests (tests/cli/t*.sh), then print one summary line "N passed, N failed".
# Environment: BIN (tool directory), BUILD (build directory), GI_ONLY=unit|cli,
# GI_TEST_FILTER (substring of test names to run).
set -u
cd "$(dirname "$0")/.."
export BIN=$(cd "${BIN:-bin}" && pwd) BUILD=$(cd "${BUILD:-build}" && pwd)
export GI_ROOT=$(pwd)
export MESA_SHADER_CACHE_DISABLE=true
export CMOCKA_MESSAGE_OUTPUT=stdout
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=0}
export LSAN_OPTIONS=${LSAN_OPTIONS:-suppressions=$GI_ROOT/tests/lsan.supp:print_suppressions=0}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
passed=0 failed=0 failures=()
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

if [ "${GI_ONLY:-}" != cli ]; then
  for t in "$@"; do
    name=$(basename "$t")
    [ -n "${GI_TEST_FILTER:-}" ] && [[ "$name" != *"$GI_TEST_FILTER"* ]] && continue
    t0=$(date +%s.%N)
    "$t" >"$tmp/out" 2>&1; rc=$?
    t1=$(date +%s.%N)
    p=$(grep -Eo '^\[  PASSED  \] [0-9]+' "$tmp/out" | awk '{s+=$4} END {print s+0}')
    f=$(grep -Eo '^\[  FAILED  \] [0-9]+' "$tmp/out" | awk '{s+=$4} END {print s+0}')
    if [ "$rc" -ne 0 ] && [ "$f" -eq 0 ]; then f=1; fi  # crash or sanitizer report
    passed=$((passed + p)); failed=$((failed + f))
    printf '%-34s %3d passed %3d failed  %6.2fs\n' "$name" "$p" "$f" "$(awk -v a="$t0" -v b="$t1" "BEGIN { print b - a }")"
    if [ "$f" -ne 0 ]; then failures+=("$name"); sed 's/^/    /' "$tmp/out" | grep -v '^    \[ \(RUN\|       OK\) ' | tail -40; fi
  done
fi

if [ "${GI_ONLY:-}" != unit ]; then
  for t in tests/cli/t[0-9]*.sh; do
    [ -e "$t" ] || continue
    name=$(basename "$t" .sh)
    [ -n "${GI_TEST_FILTER:-}" ] && [[ "$name" != *"$GI_TEST_FILTER"* ]] && continue
    t0=$(date +%s.%N)
    bash "$t" >"$tmp/out" 2>&1; rc=$?
    t1=$(date +%s.%N)
    p=$(grep -c '^ok ' "$tmp/out"); f=$(grep -c '^not ok ' "$tmp/out")
    if [ "$rc" -ne 0 ] && [ "$f" -eq 0 ]; then f=1; fi
    passed=$((passed + p)); failed=$((failed + f))
    printf '%-34s %3d passed %3d failed  %6.2fs\n' "$name" "$p" "$f" "$(awk -v a="$t0" -v b="$t1" "BEGIN { print b - a }")"
    if [ "$f" -ne 0 ]; then failures+=("$name"); sed 's/^/    /' "$tmp/out" | tail -40; fi
  done
fi

[ ${#failures[@]} -gt 0 ] && echo "failing: ${failures[*]}"
echo "$passed passed, $failed failed"
[ "$failed" -eq 0 ]
