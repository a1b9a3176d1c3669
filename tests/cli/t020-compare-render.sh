#!/usr/bin/env bash
# t020-compare-render.sh - gi-compare render on the Cornell box: EXR size and
# gi:* metadata, results independent of -j, frame selection by name and index,
# seeds, the --time budget, and the exit codes and messages of every refusal.
source "$(dirname "$0")/lib.sh"
GC=$BIN/gi-compare
B=${BUILD:-$GI_ROOT/build}
MK=$B/tools/mkimage
MC=$B/tools/mkcornell
SCRIPT=$GI_ROOT/examples/cornell-box/variants.script
if [ ! -x "$GC" ] || [ ! -x "$MK" ] || [ ! -x "$MC" ]; then
  echo "ok 1 # skip gi-compare, build/tools/mkimage or build/tools/mkcornell not built"
  exit 0
fi
"$MC" -q "$TMP/cornell.gltf" || { not_ok "mkcornell makes the scene"; finish; }
SIZE=(--size 32x32 --spp 4)

# meta FILE KEY: the value of the EXR string attribute gi:KEY (empty if absent).
INFO=()
if command -v iinfo >/dev/null; then INFO=(iinfo -v)
elif command -v oiiotool >/dev/null; then INFO=(oiiotool --info -v); fi
meta() { "${INFO[@]}" "$1" 2>/dev/null | sed -n "s/^ *gi:$2: \"\(.*\)\"\$/\1/p"; }
# val KEY: the value of KEY=... in the last command's stdout (gi-compare diff).
val() { sed -n "s/^$1=//p" "$TMP/stdout"; }
# num_ge A B: A and B are numbers and A >= B.
num_ge() { awk -v a="$1" -v b="$2" 'BEGIN { exit !(a != "" && a + 0 == a && a >= b) }'; }
# no_tmp_files: no '*.tmp.*' file anywhere under $TMP.
no_tmp_files() { [ -z "$(find "$TMP" -name '*.tmp.*' -print -quit)" ]; }

# ---- a frame, its size and metadata ------------------------------------------
expect_success "render frame 0 of the Cornell script" \
  "$GC" render "$TMP/cornell.gltf" "$SCRIPT" -o "$TMP/a.exr" "${SIZE[@]}" -j 2
check "output file exists" test -s "$TMP/a.exr"
check "output is 32x32 RGB (--size overrides the script's 512x512)" [ "$("$MK" -i "$TMP/a.exr")" = "32 32 3" ]
expect_stderr "rendered frame 'published' 32x32, 4 spp" "summary line names frame, size and spp"
expect_success "pixels are finite (diff accepts the image)" "$GC" diff "$TMP/a.exr" "$TMP/a.exr"
check "image is not black (mean $(val mean_a) cd/m^2)" num_ge "$(val mean_a)" 1e-6
if [ ${#INFO[@]} -gt 0 ]; then
  check "metadata gi:spp = 4" [ "$(meta "$TMP/a.exr" spp)" = 4 ]
  secs=$(meta "$TMP/a.exr" seconds)
  check "metadata gi:seconds is a number ($secs)" num_ge "$secs" 0
  check "metadata gi:frame = published" [ "$(meta "$TMP/a.exr" frame)" = published ]
  check "metadata gi:units = cd/m^2" [ "$(meta "$TMP/a.exr" units)" = "cd/m^2" ]
  check "metadata gi:seed = 1 (the default)" [ "$(meta "$TMP/a.exr" seed)" = 1 ]
else
  echo "ok # skip metadata checks: neither iinfo nor oiiotool (openimageio-tools) found"
fi

# ---- determinism ----------------------------------------------------------------
expect_success "render again with -j 1" \
  "$GC" render "$TMP/cornell.gltf" "$SCRIPT" -o "$TMP/a1.exr" "${SIZE[@]}" -j 1
expect_success "diff -j 1 against -j 2" "$GC" diff "$TMP/a1.exr" "$TMP/a.exr"
check "-j 1 and -j 2 give identical pixels (rms=$(val rms))" [ "$(val rms)" = 0 ]
expect_success "render with --seed 2" \
  "$GC" render "$TMP/cornell.gltf" "$SCRIPT" -o "$TMP/s2.exr" "${SIZE[@]}" --seed 2
"$GC" diff "$TMP/s2.exr" "$TMP/a.exr" >"$TMP/stdout" 2>/dev/null
check "a different seed gives a different image (rms=$(val rms))" num_ge "$(val rms)" 1e-9

# ---- the image's own noise -------------------------------------------------------
# Two renders of other seeds differ by both images' noise: the estimates that
# each wrote (from its two independently scrambled halves) must add up to it.
if [ ${#INFO[@]} -gt 0 ]; then
  for sd in 1 2; do
    for n in 16 64; do
      "$GC" render "$TMP/cornell.gltf" "$SCRIPT" -o "$TMP/n$sd-$n.exr" --size 64x64 --spp $n -s $sd -q ||
        not_ok "render 64x64 at $n spp, seed $sd"
    done
  done
  for n in 16 64; do
    e1=$(meta "$TMP/n1-$n.exr" noise_nrmse) e2=$(meta "$TMP/n2-$n.exr" noise_nrmse)
    "$GC" diff "$TMP/n1-$n.exr" "$TMP/n2-$n.exr" >"$TMP/stdout" 2>/dev/null
    got=$(val nrmse)
    check "$n spp: the noise estimates ($e1, $e2) add up to the seeds' difference ($got) within 25%" \
      awk -v a="$e1" -v b="$e2" -v d="$got" 'BEGIN { r = sqrt(a * a + b * b) / d; exit !(a > 0 && b > 0 && r > 0.8 && r < 1.25) }'
  done
  e16=$(meta "$TMP/n1-16.exr" noise_nrmse) e64=$(meta "$TMP/n1-64.exr" noise_nrmse)
  check "4x the samples about halve the estimated noise ($e16 -> $e64)" \
    awk -v a="$e16" -v b="$e64" 'BEGIN { r = b / a; exit !(r > 0.35 && r < 0.65) }'
  check "the noise rms is the noise nrmse times the mean" \
    awk -v r="$(meta "$TMP/n1-64.exr" noise_rms)" -v n="$e64" -v m="$("$GC" diff "$TMP/n1-64.exr" "$TMP/n1-64.exr" | sed -n 's/^mean_ref=//p')" \
      'BEGIN { exit !(r > 0 && (r / (n * m) - 1) ^ 2 < 1e-8) }'
  # diff reports a reference's noise and the error beyond it
  "$GC" diff "$TMP/n2-16.exr" "$TMP/n1-64.exr" >"$TMP/stdout" 2>/dev/null
  check "diff prints the reference's ref_noise_nrmse ($(val ref_noise_nrmse))" [ "$(val ref_noise_nrmse)" = "$e64" ]
  check "nrmse_excess = sqrt(nrmse^2 - ref_noise_nrmse^2) ($(val nrmse_excess))" \
    awk -v x="$(val nrmse_excess)" -v t="$(val nrmse)" -v n="$e64" 'BEGIN { exit !(x > 0 && (x * x - (t * t - n * n)) ^ 2 < 1e-12) }'
  "$GC" render "$TMP/cornell.gltf" "$SCRIPT" -o "$TMP/n1.exr" --size 16x16 --spp 1 -q || not_ok "render at 1 spp"
  check "1 spp: no noise estimate in the metadata" [ -z "$(meta "$TMP/n1.exr" noise_nrmse)" ]
  "$GC" diff "$TMP/n1-16.exr" "$TMP/n1.exr" --quiet >"$TMP/stdout" 2>/dev/null
  check "diff against a reference without an estimate prints none" [ -z "$(val ref_noise_nrmse)$(val nrmse_excess)" ]
else
  echo "ok # skip noise checks: neither iinfo nor oiiotool (openimageio-tools) found"
fi

# ---- frame selection -------------------------------------------------------------
expect_success "--frame by name (panel)" \
  "$GC" render "$TMP/cornell.gltf" "$SCRIPT" --frame panel -o "$TMP/panel.exr" "${SIZE[@]}"
expect_stderr "rendered frame 'panel'" "the named frame is rendered"
expect_success "--frame by index (3 = panel-warm)" \
  "$GC" render "$TMP/cornell.gltf" "$SCRIPT" --frame 3 -o "$TMP/f3.exr" "${SIZE[@]}"
expect_stderr "rendered frame 'panel-warm'" "index 3 is the fourth frame"
[ ${#INFO[@]} -gt 0 ] && check "metadata gi:frame = panel-warm" [ "$(meta "$TMP/f3.exr" frame)" = panel-warm ]
"$GC" diff "$TMP/f3.exr" "$TMP/panel.exr" >"$TMP/stdout" 2>/dev/null
check "panel-warm differs from panel (rms=$(val rms))" num_ge "$(val rms)" 1e-9
expect_success "--frame back-to-panel-warm (index 7)" \
  "$GC" render "$TMP/cornell.gltf" "$SCRIPT" --frame back-to-panel-warm -o "$TMP/f7.exr" "${SIZE[@]}"
"$GC" diff "$TMP/f7.exr" "$TMP/f3.exr" >"$TMP/stdout" 2>/dev/null
check "frame 7 restores frame 3 exactly (rms=$(val rms))" [ "$(val rms)" = 0 ]
expect_success "no SCRIPT: the glTF's own camera and light" \
  "$GC" render "$TMP/cornell.gltf" -o "$TMP/g.exr" "${SIZE[@]}"
printf 'camera gltf 0\nframe own\n' >"$TMP/own.script"
expect_success "a script that only selects the glTF camera" \
  "$GC" render "$TMP/cornell.gltf" "$TMP/own.script" -o "$TMP/own.exr" "${SIZE[@]}"
"$GC" diff "$TMP/g.exr" "$TMP/own.exr" >"$TMP/stdout" 2>/dev/null
check "... renders the same as no script (rms=$(val rms))" [ "$(val rms)" = 0 ]

# ---- time budget -------------------------------------------------------------------
t0=$(date +%s.%N)
expect_success "--time 0.3 with --spp 1048576" \
  "$GC" render "$TMP/cornell.gltf" "$SCRIPT" -o "$TMP/t.exr" --size 32x32 --spp 1048576 --time 0.3
t1=$(date +%s.%N)
check "--time stops early (took $(echo "$t1 - $t0" | bc) s)" awk -v a="$t0" -v b="$t1" 'BEGIN { exit !(b - a < 20) }'
if [ ${#INFO[@]} -gt 0 ]; then
  spp=$(meta "$TMP/t.exr" spp) secs=$(meta "$TMP/t.exr" seconds)
  check "fewer samples than asked ($spp spp)" awk -v s="$spp" 'BEGIN { exit !(s >= 1 && s < 1048576) }'
  check "stopped after crossing the budget ($secs s >= 0.3)" num_ge "$secs" 0.3
fi

# ---- refusals: exact exit codes, messages, no output left ------------------------
expect_exit 4 "missing scene file exits 4" "$GC" render "$TMP/nope.gltf" -o "$TMP/x.exr" "${SIZE[@]}"
expect_stderr "nope\.gltf: cannot open: No such file" "missing scene is named"
printf '{"asset": {"version": "2.0"}, "meshes": [\n' >"$TMP/broken.gltf"
expect_exit 3 "malformed glTF exits 3" "$GC" render "$TMP/broken.gltf" -o "$TMP/x.exr" "${SIZE[@]}"
expect_stderr "broken\.gltf: " "malformed scene is named"
printf 'resolution 8 8\nlight lamp point position 0 0 0 intensity bright\nframe a\n' >"$TMP/bad.script"
expect_exit 3 "script with a syntax error exits 3" \
  "$GC" render "$TMP/cornell.gltf" "$TMP/bad.script" -o "$TMP/x.exr" "${SIZE[@]}"
expect_stderr "bad\.script:2:43: expected a number after 'intensity', got 'bright'" \
  "script error gives file:line:column"
printf 'material Nope roughness 1\nframe a\n' >"$TMP/foreign.script"
expect_exit 3 "script naming a material the scene lacks exits 3" \
  "$GC" render "$TMP/cornell.gltf" "$TMP/foreign.script" -o "$TMP/x.exr" "${SIZE[@]}"
expect_stderr "foreign\.script:1:10: .*got 'Nope'" "scene check gives file:line:column"
expect_exit 2 "unknown frame name exits 2" \
  "$GC" render "$TMP/cornell.gltf" "$SCRIPT" --frame nosuch -o "$TMP/x.exr" "${SIZE[@]}"
expect_stderr "no frame 'nosuch' \(the script has 8 frames\)" "unknown frame message counts the frames"
expect_exit 2 "frame index out of range exits 2" \
  "$GC" render "$TMP/cornell.gltf" "$SCRIPT" --frame 8 -o "$TMP/x.exr" "${SIZE[@]}"
expect_exit 2 "--frame without a SCRIPT exits 2" \
  "$GC" render "$TMP/cornell.gltf" --frame 0 -o "$TMP/x.exr" "${SIZE[@]}"

# A one-triangle scene without a camera (embedded buffer: (0,0,0) (1,0,0) (0,1,0)).
cat >"$TMP/nocam.gltf" <<'EOF'
{"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],
 "meshes":[{"primitives":[{"attributes":{"POSITION":0},"indices":1}]}],
 "accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3"},
              {"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"}],
 "bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":36},{"buffer":0,"byteOffset":36,"byteLength":6}],
 "buffers":[{"byteLength":44,"uri":"data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAAAAABAAIAAAA="}]}
EOF
expect_exit 3 "no script and a scene without a camera exits 3" \
  "$GC" render "$TMP/nocam.gltf" -o "$TMP/x.exr" "${SIZE[@]}"
expect_stderr "nocam\.gltf: frame '.*' has no camera" "missing camera is explained"
printf 'resolution 8 8\nframe lightsonly\n' >"$TMP/nocam.script"
expect_exit 3 "a script frame without a camera exits 3" \
  "$GC" render "$TMP/cornell.gltf" "$TMP/nocam.script" -o "$TMP/x.exr" "${SIZE[@]}"
expect_stderr "nocam\.script: frame 'lightsonly' has no camera" "the script and frame are named"

expect_exit 2 "missing -o exits 2" "$GC" render "$TMP/cornell.gltf" "$SCRIPT" "${SIZE[@]}"
expect_stderr "missing -o" "missing -o is explained"
expect_exit 2 "--spp 0 exits 2" "$GC" render "$TMP/cornell.gltf" -o "$TMP/x.exr" --spp 0
expect_stderr "--spp: 0 is out of range" "--spp range error names the option"
expect_exit 2 "--spp abc exits 2" "$GC" render "$TMP/cornell.gltf" -o "$TMP/x.exr" --spp abc
expect_stderr "--spp: expected an integer, got 'abc'" "--spp parse error quotes the value"
expect_exit 2 "--size 0x4 exits 2" "$GC" render "$TMP/cornell.gltf" -o "$TMP/x.exr" --size 0x4
expect_exit 2 "--time -1 exits 2" "$GC" render "$TMP/cornell.gltf" -o "$TMP/x.exr" --time -1
expect_exit 2 "three positional arguments exit 2" \
  "$GC" render "$TMP/cornell.gltf" "$SCRIPT" "$SCRIPT" -o "$TMP/x.exr"
expect_exit 2 "unknown option exits 2" "$GC" render --frobnicate "$TMP/cornell.gltf" -o "$TMP/x.exr"
check "no output was written by any refused command" test ! -e "$TMP/x.exr"

expect_exit 4 "output into a missing directory exits 4" \
  "$GC" render "$TMP/cornell.gltf" -o "$TMP/no/such/dir/x.exr" "${SIZE[@]}"
expect_stderr "no/such/dir/x\.exr" "the output path is named"
expect_stderr "cannot write into '.*no/such/dir'" "refused before the render (its directory checked first)"
check "no partial output or temporary file left" no_tmp_files
check "the missing directory was not created" test ! -e "$TMP/no"

cp "$TMP/a.exr" "$TMP/keep.exr"
expect_exit 3 "a failing render keeps an existing output" \
  "$GC" render "$TMP/broken.gltf" -o "$TMP/keep.exr" "${SIZE[@]}"
check "... byte for byte" cmp -s "$TMP/keep.exr" "$TMP/a.exr"

expect_exit 0 "--help exits 0" "$GC" render --help
expect_stdout "^usage: gi-compare render SCENE \[SCRIPT\] -o OUT\.exr" "--help prints usage on stdout"
check "--help prints nothing on stderr" test ! -s "$TMP/stderr"

finish
