#!/usr/bin/env bash
# t030-compare-diff.sh - gi-compare diff: exact statistics on known images,
# tolerance exit codes, error image, and refusal of mismatched or bad inputs.
source "$(dirname "$0")/lib.sh"
GC=$BIN/gi-compare
MK=${BUILD:-$GI_ROOT/build}/tools/mkimage
if [ ! -x "$GC" ] || [ ! -x "$MK" ]; then
  echo "ok 1 # skip gi-compare or build/tools/mkimage not built"
  exit 0
fi

# val KEY: the value of KEY=... in the last command's stdout.
val() { sed -n "s/^$1=//p" "$TMP/stdout"; }
# near A B TOL: |A - B| <= TOL (relative to max(1, |B|)).
near() { awk -v a="$1" -v b="$2" -v t="$3" 'BEGIN { d = a - b; if (d < 0) d = -d;
  m = b < 0 ? -b : b; if (m < 1) m = 1; exit !(a != "" && d <= t * m) }'; }

mk() { "$MK" "$@" || { not_ok "mkimage $*"; finish; }; }
mk "$TMP/ramp.exr" 16 8 3 ramp 0.5 0.01
mk "$TMP/a.exr" 8 4 3 const 1.25 2.5 0.75
mk "$TMP/ref.exr" 8 4 3 const 1 2 1
mk "$TMP/small.exr" 4 4 3 const 1
mk "$TMP/nan.exr" 8 4 3 nan 3 2 1
mk "$TMP/inf.exr" 8 4 3 inf 7 0 2
mk "$TMP/gray.exr" 8 4 1 const 2
mk "$TMP/gray2.exr" 8 4 1 const 2.5
mk "$TMP/rgba.exr" 8 4 4 const 1.25 2.5 0.75 0.5
mk "$TMP/zero.exr" 8 4 3 const 0
mk "$TMP/half.exr" 8 4 3 const 0.5

# identical images
expect_success "identical images exit 0" "$GC" diff "$TMP/ramp.exr" "$TMP/ramp.exr"
check "identical: rms=0" [ "$(val rms)" = 0 ]
check "identical: nrmse=0" [ "$(val nrmse)" = 0 ]
check "identical: max_abs=0" [ "$(val max_abs)" = 0 ]
check "identical: psnr=inf" [ "$(val psnr)" = inf ]
check "identical: size keys" [ "$(val width)x$(val height) $(val pixels)" = "16x8 128" ]

# known per-channel offsets: a - ref = (0.25, 0.5, -0.25) everywhere
expect_success "constant offset exits 0 without --tolerance" "$GC" diff "$TMP/a.exr" "$TMP/ref.exr"
read -r e_rms e_nrmse e_rel e_psnr < <(awk 'BEGIN {
  mse = (0.25^2 + 0.5^2 + 0.25^2) / 3; rms = sqrt(mse); mean = (1 + 2 + 1) / 3;
  rel = (0.0625 / 1.01 + 0.25 / 4.01 + 0.0625 / 1.01) / 3;
  printf "%.12g %.12g %.12g %.12g\n", rms, rms / mean, rel, 10 * log(4 / mse) / log(10) }')
check "offset: rms = sqrt(mean of squared offsets)" near "$(val rms)" "$e_rms" 1e-7
check "offset: nrmse = rms / mean(ref)" near "$(val nrmse)" "$e_nrmse" 1e-7
check "offset: relmse" near "$(val relmse)" "$e_rel" 1e-7
check "offset: psnr with peak = max(ref) = 2" near "$(val psnr)" "$e_psnr" 1e-7
check "offset: max_abs = 0.5" near "$(val max_abs)" 0.5 1e-9
check "offset: per-channel rms" [ "$(val rms_r) $(val rms_g) $(val rms_b)" = "0.25 0.5 0.25" ]
check "offset: per-channel nrmse" [ "$(val nrmse_r) $(val nrmse_g) $(val nrmse_b)" = "0.25 0.25 0.25" ]
check "offset: mean_a" [ "$(val mean_a)" = 1.5 ]
check "offset: mean_ref" near "$(val mean_ref)" 1.333333333 1e-8

# tolerance
t_below=$(awk -v n="$e_nrmse" 'BEGIN { printf "%.6f", n * 0.99 }')
t_above=$(awk -v n="$e_nrmse" 'BEGIN { printf "%.6f", n * 1.01 }')
expect_exit 1 "nrmse above --tolerance exits 1" "$GC" diff --tolerance "$t_below" "$TMP/a.exr" "$TMP/ref.exr"
expect_stderr "exceeds tolerance" "tolerance failure is explained on stderr"
check "statistics still printed when beyond tolerance" near "$(val nrmse)" "$e_nrmse" 1e-7
expect_exit 0 "nrmse below --tolerance exits 0" "$GC" diff -t "$t_above" "$TMP/a.exr" "$TMP/ref.exr"
expect_exit 0 "identical images pass --tolerance 0" "$GC" diff -t 0 "$TMP/ramp.exr" "$TMP/ramp.exr"

# channel handling
expect_success "RGBA against RGB compares RGB" "$GC" diff "$TMP/rgba.exr" "$TMP/ref.exr"
check "RGBA: alpha ignored, same rms" near "$(val rms)" "$e_rms" 1e-7
expect_success "gray against gray" "$GC" diff "$TMP/gray2.exr" "$TMP/gray.exr"
check "gray: rms_y and nrmse" [ "$(val rms_y) $(val nrmse)" = "0.5 0.25" ]
expect_exit 3 "gray against RGB is refused" "$GC" diff "$TMP/gray.exr" "$TMP/ref.exr"
expect_stderr "gray.exr has 1 channel but .*ref.exr has 3" "channel mismatch names both files"

# bad inputs
expect_exit 3 "size mismatch exits 3" "$GC" diff "$TMP/small.exr" "$TMP/ref.exr"
expect_stderr "small.exr is 4x4 but .*ref.exr is 8x4" "size mismatch message gives both sizes"
expect_exit 3 "NaN pixel exits 3" "$GC" diff "$TMP/nan.exr" "$TMP/ref.exr"
expect_stderr "nan.exr: pixel \(3, 2\) channel G is nan" "NaN message names file, pixel and channel"
expect_exit 3 "Inf in the reference exits 3" "$GC" diff "$TMP/ref.exr" "$TMP/inf.exr"
expect_stderr "inf.exr: pixel \(7, 0\) channel B is \+inf" "Inf message names file, pixel and channel"
expect_exit 4 "missing file exits 4" "$GC" diff "$TMP/nope.exr" "$TMP/ref.exr"
expect_stderr "nope.exr: cannot open: No such file" "missing file is named"
printf 'not an image\n' >"$TMP/junk.exr"
expect_exit 3 "undecodable file exits 3" "$GC" diff "$TMP/junk.exr" "$TMP/ref.exr"
expect_exit 3 "zero-mean reference exits 3" "$GC" diff "$TMP/half.exr" "$TMP/zero.exr"
expect_stderr "zero.exr: mean reference value is 0.*undefined" "zero-mean reference is explained"
expect_success "two black images match" "$GC" diff "$TMP/zero.exr" "$TMP/zero.exr"
check "two black images: nrmse=0" [ "$(val nrmse)" = 0 ]

# usage
expect_exit 2 "one image is a usage error" "$GC" diff "$TMP/ref.exr"
expect_exit 2 "negative tolerance is a usage error" "$GC" diff -t -1 "$TMP/a.exr" "$TMP/ref.exr"
expect_exit 2 "non-numeric tolerance is a usage error" "$GC" diff -t 1x "$TMP/a.exr" "$TMP/ref.exr"
expect_stderr "'1x'" "usage error names the bad value"
expect_exit 2 "unknown option is a usage error" "$GC" diff --frobnicate "$TMP/a.exr" "$TMP/ref.exr"
expect_success "--help exits 0" "$GC" diff --help
expect_stdout "usage: gi-compare diff" "--help prints usage on stdout"

# error image: a spot of 100% error on an otherwise exact image
mk "$TMP/spot.exr" 200 50 3 spot 1 5 7 2
mk "$TMP/one.exr" 200 50 3 const 1
expect_success "diff with --error-image" "$GC" diff -e "$TMP/err.png" "$TMP/spot.exr" "$TMP/one.exr"
check "error image: PNG signature" [ "$(head -c 8 "$TMP/err.png" | od -An -tx1 | tr -d ' \n')" = 89504e470d0a1a0a ]
check "error image: image plus 40-pixel legend strip" [ "$("$MK" -i "$TMP/err.png")" = "200 90 3" ]
check "error image: exact pixel is the bottom of the scale" [ "$("$MK" -i "$TMP/err.png" 0 0)" = "68 1 84" ]
spot=$("$MK" -i "$TMP/err.png" 5 7)
check "error image: 100% error pixel is the top of the scale ($spot)" \
  awk -v s="$spot" 'BEGIN { split(s, c, " "); exit !(c[1] >= 240 && c[2] >= 220 && c[3] <= 60) }'
legend=$("$MK" -i "$TMP/err.png" 0 74 200 | sort -u | wc -l)
check "error image: legend strip has labels ($legend colours on a text row)" [ "$legend" -ge 2 ]
bar=$("$MK" -i "$TMP/err.png" 20 60 161 | sort -u | wc -l)
check "error image: colour bar varies along its length ($bar colours)" [ "$bar" -ge 50 ]
mk "$TMP/tiny.exr" 40 20 3 const 1
expect_success "error image of a narrow image" "$GC" diff -e "$TMP/tiny.png" "$TMP/tiny.exr" "$TMP/tiny.exr"
check "narrow image: map widened to fit the legend" [ "$("$MK" -i "$TMP/tiny.png")" = "160 60 3" ]
expect_exit 4 "error image into a missing directory exits 4" \
  "$GC" diff -e "$TMP/no/such/err.png" "$TMP/spot.exr" "$TMP/one.exr"
expect_stderr "cannot write into '.*no/such'" "refused before the comparison (its directory checked first)"
expect_stdout_empty() { if [ -s "$TMP/stdout" ]; then not_ok "$1 (stdout not empty)"; else ok "$1"; fi; }
expect_stdout_empty "no error lines printed for a comparison that could not write its map"
check "no temporary file left behind" [ -z "$(ls -A "$TMP" | grep '\.tmp\.')" ]
expect_exit 2 "error image over an input is refused" "$GC" diff -e "$TMP/one.exr" "$TMP/spot.exr" "$TMP/one.exr"

finish
