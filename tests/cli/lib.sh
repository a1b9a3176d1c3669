# tests/cli/lib.sh - helpers for the CLI tests (sourced). Each check prints
# "ok N - what" or "not ok N - what" (TAP style); tests/run.sh counts them.
# Death by signal (exit > 128) is always a failure, even where failure is expected.
set -u
: "${BIN:?BIN must point at the tool directory}"
: "${GI_ROOT:=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)}"
export PATH="$BIN:$PATH"
export MESA_SHADER_CACHE_DISABLE=true
SHARED=${GI_SHARED:-$GI_ROOT/../shared}
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
_n=0
_fail=0

ok()     { _n=$((_n + 1)); echo "ok $_n - $*"; }
not_ok() { _n=$((_n + 1)); _fail=1; echo "not ok $_n - $*"; }

# expect_success WHAT CMD...: the command exits 0.
expect_success() {
  local what=$1; shift
  "$@" >"$TMP/stdout" 2>"$TMP/stderr"; local rc=$?
  if [ $rc -eq 0 ]; then ok "$what"; else not_ok "$what (exit $rc)"; sed 's/^/#   /' "$TMP/stderr" | tail -5; fi
}

# expect_exit CODE WHAT CMD...: the command exits with CODE exactly (never a signal).
expect_exit() {
  local code=$1 what=$2; shift 2
  "$@" >"$TMP/stdout" 2>"$TMP/stderr"; local rc=$?
  if [ $rc -eq "$code" ]; then ok "$what"; else not_ok "$what (exit $rc, wanted $code)"; sed 's/^/#   /' "$TMP/stderr" | tail -5; fi
}

# expect_stderr PATTERN WHAT: the last command's stderr matches the extended regex.
expect_stderr() {
  if grep -Eq -- "$1" "$TMP/stderr"; then ok "$2"; else not_ok "$2 (stderr lacks /$1/)"; sed 's/^/#   /' "$TMP/stderr" | tail -5; fi
}
# expect_stdout PATTERN WHAT: the last command's stdout matches the extended regex.
expect_stdout() {
  if grep -Eq -- "$1" "$TMP/stdout"; then ok "$2"; else not_ok "$2 (stdout lacks /$1/)"; sed 's/^/#   /' "$TMP/stdout" | tail -5; fi
}

# check WHAT CMD...: any command as a boolean assertion.
check() {
  local what=$1; shift
  if "$@"; then ok "$what"; else not_ok "$what"; fi
}

finish() { exit $_fail; }
# Accuracy tests against long references run in the plain build only.
skip_under_sanitizers() {
  if [ "${GI_SANITIZE:-0}" = 1 ]; then
    echo "# skipped under SANITIZE=1 (references too slow); runs in the plain build"
    finish
  fi
}

# gpoints_vs_sensors SCENE SCRIPT GPOINTS: every 16th gathering point of a gi-relight --gpoints
# file against the path tracer's indirect illuminance there (gi-compare sensors --min-bounces 1,
# 1024 spp); sets ratio to the sum of the first over the sum of the second ("" with 1000
# points or fewer).
gpoints_vs_sensors() {
  awk '!/^#/ && NR % 16 == 0 { print $1, $2, $3, $4, $5, $6 }' "$3" >"$TMP/p.pts"
  awk '!/^#/ && NR % 16 == 0 { print $8 }' "$3" >"$TMP/p.e"
  expect_success "sensors at the points, 1024 spp" gi-compare sensors -q "$1" "$2" --points "$TMP/p.pts" \
    --spp 1024 --min-bounces 1
  cp "$TMP/stdout" "$TMP/p.sens"
  ratio=$(paste "$TMP/p.e" "$TMP/p.sens" | awk '{ a += $1; b += $2 } END { if (NR > 1000 && b > 0) printf "%.4f", a / b }')
}

# direct_vs_reference SCENE SCRIPT FRAME SPP: gi-precompute (100 k photons) and gi-hvds of
# SCENE, the relight's direct light of FRAME (--only direct) and the path tracer's
# (--max-bounces 0, SPP samples a pixel); sets nrmse to the first's error against the second.
direct_vs_reference() {
  expect_success "precompute" gi-precompute -q "$1" -o "$TMP/d.gip" --photons 100000
  expect_success "hvds" gi-hvds -q "$1" "$TMP/d.gip" -o "$TMP/d.gih"
  expect_success "relight, direct light" gi-relight -q "$1" "$TMP/d.gip" "$TMP/d.gih" "$2" -o "$TMP/dout" --only direct
  expect_success "reference, direct light, $4 spp" gi-compare render -q "$1" "$2" --frame "$3" --spp "$4" \
    --max-bounces 0 -o "$TMP/dref.exr"
  nrmse=$(gi-compare diff "$TMP/dout/$3.exr" "$TMP/dref.exr" | awk -F= '$1 == "nrmse" { print $2 }')
}
