# shellcheck shell=bash
# bench/lib.sh - helpers of bench/run.sh (sourced, not run): failure bookkeeping,
# peak-memory measurement, cache keys, EXR metadata, summary-line parsing.
# Needs: BIN, RAW (set by run.sh). Bash only; awk is POSIX (mawk works).

# ---- failures: remember them, keep going where possible, exit non-zero at the end

BENCH_RC=0          # exit status of the first failing command (0: none failed)
BENCH_FAILS=()      # one line per failure

# bench_fail RC WHAT: record a failed stage.
bench_fail() {
  local rc=$1; shift
  [ "$rc" -ne 0 ] || rc=1
  echo "bench: FAILED (exit $rc): $*" >&2
  BENCH_FAILS+=("$* (exit $rc)")
  [ "$BENCH_RC" -ne 0 ] || BENCH_RC=$rc
}

say() { echo "bench: $*" >&2; }

# ---- measuring: wall seconds and peak resident size ------------------------------

# measure LOG CMD...: run CMD with stderr to LOG (stdout too), then set M_SEC (wall
# seconds) and M_KB (peak resident set size in KiB, as the kernel counts it: the
# ru_maxrss of GNU time, or VmHWM polled from /proc without it). Returns CMD's status.
M_SEC=""; M_KB=""
measure() {
  local log=$1; shift
  local tf rc
  tf=$(mktemp "${TMPDIR:-/tmp}/gi-bench-time.XXXXXX")
  if [ -x /usr/bin/time ] && [ -z "${BENCH_NO_GNU_TIME:-}" ]; then
    /usr/bin/time -f '%e %M' -o "$tf" "$@" >"$log" 2>&1 && rc=0 || rc=$?
  else
    "$BENCH_DIR/peakmem.sh" "$tf" "$@" >"$log" 2>&1 && rc=0 || rc=$?
  fi
  # GNU time prepends "Command exited with non-zero status N" on failure.
  read -r M_SEC M_KB < <(tail -n 1 "$tf") || true
  rm -f "$tf"
  M_SEC=${M_SEC:-0}; M_KB=${M_KB:-0}
  return "$rc"
}

# ---- numbers ---------------------------------------------------------------------

# calc EXPR: evaluate an awk expression, print with 6 significant digits.
calc() { awk "BEGIN { v = $1; printf \"%.6g\n\", v }"; }

# mean_of: mean of the numbers on stdin (one per line), "nan" if none.
mean_of() { awk '{ s += $1; n++ } END { if (n) printf "%.6g\n", s / n; else print "nan" }'; }

# mb BYTES: megabytes with one decimal.
mb() { awk -v b="$1" 'BEGIN { printf "%.1f", b / 1e6 }'; }

# fsize FILE: size in bytes (0 if missing).
fsize() { stat -c %s "$1" 2>/dev/null || echo 0; }

# ---- EXR metadata and image comparison -------------------------------------------

# exr_attr FILE NAME: a string attribute gi-compare render writes (gi:seconds, gi:spp, ...).
exr_attr() {
  iinfo -v "$1" 2>/dev/null | awk -F'"' -v k="$2:" '$1 ~ k { print $2; exit }'
}

# nrmse IMAGE REFERENCE: the nrmse printed by gi-compare diff; empty on failure.
nrmse() {
  "$BIN/gi-compare" diff -q "$1" "$2" 2>>"$RAW/diff.log" | awk -F= '$1 == "nrmse" { print $2 }'
}

# ---- cache keys ------------------------------------------------------------------

# scene_hash GLTF: content hash of the glTF and the files its "uri"s name beside it
# (buffers and textures; data: URIs are inside the glTF already).
scene_hash() {
  local g=$1 d u
  d=$(dirname "$g")
  {
    sha256sum < "$g"
    grep -o '"uri"[[:space:]]*:[[:space:]]*"[^"]*"' "$g" | sed 's/.*"\([^"]*\)"$/\1/' |
      grep -v '^data:' | sort -u | while IFS= read -r u; do
        [ -f "$d/$u" ] && { printf '%s ' "$u"; sha256sum < "$d/$u"; }
      done
  } | sha256sum | cut -c1-16
}

# pt_hash: content hash of the sources that decide a path-traced pixel (the path tracer,
# BRDF, lights, ray tracing, scene loading and script), so that a change to any of them
# renders the references again.
pt_hash() {
  local r=${ROOT:-.}
  cat "$r"/common/gi_pt.[ch] "$r"/common/gi_brdf.[ch] "$r"/common/gi_light.[ch] "$r"/common/gi_emit.[ch] "$r"/common/gi_rt.[ch] \
      "$r"/common/gi_scene.[ch] "$r"/common/gi_script.[ch] "$r"/common/gi_rng.h 2>/dev/null |
    sha256sum | cut -c1-16
}

# cache_key SCENE_HASH SCRIPT FRAME WxH SPP SEED: key of one rendered image.
cache_key() {
  { echo "scene $1"; echo "pt ${PT_HASH:-$(pt_hash)}"; echo "frame $3 size $4 spp $5 seed $6"; cat "$2"; } |
    sha256sum | cut -c1-20
}

# ---- summary lines of the tools (stderr) -------------------------------------------

# grab LOG REGEX: first match of REGEX (grep -o) in LOG, first number in it.
grab() {
  grep -oE "$2" "$1" 2>/dev/null | head -n 1 | grep -oE '[0-9]+(\.[0-9]+)?' | head -n 1
}
