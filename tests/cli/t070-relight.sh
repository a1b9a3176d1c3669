#!/usr/bin/env bash
# t070-relight.sh - gi-relight from the command line on a small Cornell box:
# one EXR (and PNG) per frame, the timings CSV and its 'changed' column, what
# a camera, light or material change recomputes, --frames, the same pixels for
# any -j, every refusal before any rendering (exit 2, 3, 4 and no output), and
# a smoke comparison of two frames against the path-traced reference.
source "$(dirname "$0")/lib.sh"
GR=$BIN/gi-relight
GH=$BIN/gi-hvds
GP=$BIN/gi-precompute
GC=$BIN/gi-compare
B=${BUILD:-$GI_ROOT/build}
MC=$B/tools/mkcornell
MK=$B/tools/mkimage
for t in "$GR" "$GH" "$GP" "$GC" "$MC" "$MK"; do
  if [ ! -x "$t" ]; then echo "ok 1 # skip $t not built"; exit 0; fi
done
# LeakSanitizer (make test SANITIZE=1): Mesa's llvmpipe keeps about 480 bytes per
# process that no OSMesa call frees; suppress them unless the caller set LSAN_OPTIONS.
if [ -z "${LSAN_OPTIONS:-}" ]; then
  printf 'leak:libOSMesa.so\n' >"$TMP/lsan.supp"
  export LSAN_OPTIONS=suppressions=$TMP/lsan.supp:print_suppressions=0
fi
C=$TMP/c.gltf
"$MC" -q "$C" || { not_ok "mkcornell makes the scene"; finish; }
"$GP" "$C" -o "$TMP/c.gip" --photons 50000 -q || { not_ok "gi-precompute makes the .gip"; finish; }
"$GH" "$C" "$TMP/c.gip" -o "$TMP/c.gih" --gather-rays 16 --r-max 0.05 -q ||
  { not_ok "gi-hvds makes the .gih"; finish; }
IN=("$C" "$TMP/c.gip" "$TMP/c.gih")

# val KEY: the value of KEY=... in the last command's stdout (gi-compare diff).
val() { sed -n "s/^$1=//p" "$TMP/stdout"; }
# lt A B: A and B are numbers and A < B.
lt() { awk -v a="$1" -v b="$2" 'BEGIN { exit !(a != "" && a + 0 == a && a < b) }'; }
# col CSV ROW NAME: the value of column NAME in data row ROW (1-based) of CSV.
col() {
  awk -F, -v r="$2" -v n="$3" 'NR == 1 { for (i = 1; i <= NF; i++) if ($i == n) c = i }
                               NR == r + 1 && c { print $c }' "$1"
}
# rows CSV: the number of data rows.
rows() { echo $(($(wc -l <"$1") - 1)); }

# Four 64x64 frames, each changing one thing: camera, light, material.
cat >"$TMP/v.script" <<'EOF'
resolution 64 64
camera position 0.278 0.273 -0.8 target 0.278 0.273 0 up 0 1 0 fov 39.3076
frame base
camera position 0.45 0.40 -0.45 target 0.25 0.20 0.30 up 0 1 0 fov 45
frame moved
light ceiling point position 0.278 0.40 0.2795 intensity 2
frame lamp
material LeftWall basecolor 0.1 0.2 0.6
frame blue-wall
EOF
HEADER="frame,name,changed,width,height,t_direct_ms,t_photon_energies_ms,t_hvds_ms,t_final_gather_ms,t_splat_ms,t_materials_ms,t_gbuffer_ms,t_total_ms"

# ---- help ---------------------------------------------------------------------------------
expect_success "--help exits 0" "$GR" --help
expect_stdout '^usage: gi-relight SCENE SCENE\.gip SCENE\.gih SCRIPT -o OUTDIR' "--help prints the usage on stdout"
check "--help writes nothing on stderr" test ! -s "$TMP/stderr"

# ---- every frame, PNG, timings ---------------------------------------------------------------
O=$TMP/out
expect_success "four frames render (--png --timings -j 2)" \
  "$GR" "${IN[@]}" "$TMP/v.script" -o "$O" --png --timings "$TMP/t.csv" -j 2
for f in base moved lamp blue-wall; do
  check "$f.exr is 64x64 RGB" [ "$("$MK" -i "$O/$f.exr" 2>/dev/null)" = "64 64 3" ]
  check "$f.png is 64x64 RGB" [ "$("$MK" -i "$O/$f.png" 2>/dev/null)" = "64 64 3" ]
done
check "nothing else in OUTDIR" [ "$(ls "$O" | wc -l)" = 8 ]
expect_stderr "frame 3 'blue-wall' \(materials\): [0-9.]+ ms" "each frame is reported on stderr"
check "nothing on stdout" test ! -s "$TMP/stdout"
"$GC" diff "$O/base.exr" "$O/base.exr" >"$TMP/stdout" 2>/dev/null
check "the image is not black (mean $(val mean_a) cd/m^2)" lt 0.01 "$(val mean_a)"

T=$TMP/t.csv
check "timings: the header" [ "$(head -n 1 "$T")" = "$HEADER" ]
check "timings: one row per frame ($(rows "$T"))" [ "$(rows "$T")" = 4 ]
check "timings: frame indices 0..3" [ "$(cut -d, -f1 "$T" | tail -n +2 | tr '\n' ' ')" = "0 1 2 3 " ]
check "timings: the first frame changed 'lights materials camera'" \
  [ "$(col "$T" 1 changed)" = "lights materials camera" ]
check "timings: a camera move changed 'camera'" [ "$(col "$T" 2 changed)" = camera ]
check "timings: a moved light changed 'lights'" [ "$(col "$T" 3 changed)" = lights ]
check "timings: a recoloured wall changed 'materials'" [ "$(col "$T" 4 changed)" = materials ]
check "timings: width and height" [ "$(col "$T" 4 width)x$(col "$T" 4 height)" = 64x64 ]
# (the final gather runs on demand, for the gathering points a view reads: a
# camera move gathers those it sees for the first time since the lights
# changed, so its t_final_gather_ms need not be 0; test_hvds checks the values)
for s in t_photon_energies_ms t_hvds_ms t_materials_ms; do
  check "a camera move skips the object-space stages ($s = $(col "$T" 2 $s))" [ "$(col "$T" 2 $s)" = 0.000 ]
done
check "a light move recomputes the photon energies ($(col "$T" 3 t_photon_energies_ms) ms)" \
  lt 0 "$(col "$T" 3 t_photon_energies_ms)"
check "a light move recomputes no material ($(col "$T" 3 t_materials_ms))" [ "$(col "$T" 3 t_materials_ms)" = 0.000 ]
check "a material change recomputes reflectances ($(col "$T" 4 t_materials_ms) ms)" \
  lt 0 "$(col "$T" 4 t_materials_ms)"
check "a material change recomputes the photon energies ($(col "$T" 4 t_photon_energies_ms) ms)" \
  lt 0 "$(col "$T" 4 t_photon_energies_ms)"
check "every frame's total time is positive" \
  awk -F, 'NR > 1 && !($13 + 0 > 0) { bad = 1 } END { exit bad }' "$T"

expect_success "the same frames with -j 1" "$GR" "${IN[@]}" "$TMP/v.script" -o "$TMP/j1" -j 1 -q
for f in base blue-wall; do
  "$GC" diff "$TMP/j1/$f.exr" "$O/$f.exr" >"$TMP/stdout" 2>/dev/null
  check "$f: -j 1 and -j 2 give the same pixels (rms=$(val rms))" [ "$(val rms)" = 0 ]
done

# ---- --frames -------------------------------------------------------------------------------------
expect_success "--frames 1-2" "$GR" "${IN[@]}" "$TMP/v.script" -o "$TMP/f12" --frames 1-2 --timings "$TMP/f12.csv" -q
check "--frames 1-2 writes moved.exr and lamp.exr only" [ "$(ls "$TMP/f12" | tr '\n' ' ')" = "lamp.exr moved.exr " ]
check "... and two timing rows, frames 1 and 2" [ "$(cut -d, -f1 "$TMP/f12.csv" | tail -n +2 | tr '\n' ' ')" = "1 2 " ]
check "... the first of them changed 'lights materials camera'" \
  [ "$(col "$TMP/f12.csv" 1 changed)" = "lights materials camera" ]
"$GC" diff "$TMP/f12/lamp.exr" "$O/lamp.exr" >"$TMP/stdout" 2>/dev/null
check "... and frame 2 is the same as in the full run (rms=$(val rms))" [ "$(val rms)" = 0 ]
# Direct light is cached per light and view; a material change recomputes only the pixels
# that see it. With the cache off every frame is computed afresh: the same pixels.
expect_success "the same frames with the direct-light cache off" \
  env GI_RELIGHT_NO_CACHE=1 "$GR" "${IN[@]}" "$TMP/v.script" -o "$TMP/nc" -q
for f in base moved lamp blue-wall; do
  "$GC" diff "$TMP/nc/$f.exr" "$O/$f.exr" >"$TMP/stdout" 2>/dev/null
  check "$f: cached and fresh direct light give the same pixels (rms=$(val rms))" [ "$(val rms)" = 0 ]
done
# --edge-refine finds its extra samples when a light first needs them: the
# frames still do not depend on what came before
expect_success "--edge-refine, cached" "$GR" "${IN[@]}" "$TMP/v.script" -o "$TMP/er" --aa 3 --edge-refine -q
expect_success "--edge-refine, cache off" \
  env GI_RELIGHT_NO_CACHE=1 "$GR" "${IN[@]}" "$TMP/v.script" -o "$TMP/ernc" --aa 3 --edge-refine -q
for f in base moved lamp blue-wall; do
  "$GC" diff "$TMP/ernc/$f.exr" "$TMP/er/$f.exr" >"$TMP/stdout" 2>/dev/null
  check "--edge-refine $f: cached and fresh give the same pixels (rms=$(val rms))" [ "$(val rms)" = 0 ]
done
expect_success "--edge-refine, frame lamp alone" "$GR" "${IN[@]}" "$TMP/v.script" -o "$TMP/er1" --aa 3 --edge-refine \
  --frames lamp -q
"$GC" diff "$TMP/er1/lamp.exr" "$TMP/er/lamp.exr" >"$TMP/stdout" 2>/dev/null
check "--edge-refine lamp alone is the same as after the other frames (rms=$(val rms))" [ "$(val rms)" = 0 ]
# Both light caches keep a few buffers allocated up front and reuse the least
# recently used one: forty states of a moving lamp beside a fixed one (more
# states than either cache holds: 32 each), then back to the first and the sixth. A
# state that comes back, from the cache or retraced into a reused buffer, and
# the same frame alone give the same pixels.
{
  printf 'resolution 48 48\ncamera position 0.278 0.273 -0.8 target 0.278 0.273 0 up 0 1 0 fov 39.3076\n'
  printf 'light fixed point position 0.1 0.45 0.2 intensity 1\n'
  for i in $(seq 0 39); do
    printf 'light lamp point position 0.%02d 0.40 0.2795 intensity 2\nframe p%d\n' $((10 + i)) "$i"
  done
  printf 'light lamp point position 0.10 0.40 0.2795 intensity 2\nframe back0\n'
  printf 'light lamp point position 0.15 0.40 0.2795 intensity 2\nframe back5\n'
} >"$TMP/many.script"
expect_success "forty-two light states in one run" "$GR" "${IN[@]}" "$TMP/many.script" -o "$TMP/many" -q
expect_success "... and the sixth alone" "$GR" "${IN[@]}" "$TMP/many.script" -o "$TMP/many5" --frames p5 -q
for pair in "back0 p0" "back5 p5"; do
  set -- $pair
  "$GC" diff "$TMP/many/$1.exr" "$TMP/many/$2.exr" >"$TMP/stdout" 2>/dev/null
  check "$1 (a light state seen before) is the same as $2 (rms=$(val rms))" [ "$(val rms)" = 0 ]
done
"$GC" diff "$TMP/many5/p5.exr" "$TMP/many/p5.exr" >"$TMP/stdout" 2>/dev/null
check "p5 alone is the same as after five other states (rms=$(val rms))" [ "$(val rms)" = 0 ]
# Twelve lamps on at once, then one of them moved: the move recomputes that
# lamp's direct light only (the cache held 8 lights before, and a move then
# recomputed the 4 it could not hold as well)
{
  printf 'resolution 32 32\ncamera position 0.278 0.273 -0.8 target 0.278 0.273 0 up 0 1 0 fov 39.3076\n'
  for i in $(seq 0 11); do
    printf 'light l%d point position 0.%02d 0.40 0.2795 intensity 0.5\n' "$i" $((10 + 3 * i))
  done
  printf 'frame twelve\nlight l5 point position 0.30 0.30 0.2 intensity 0.5\nframe moved\n'
} >"$TMP/twelve.script"
expect_success "twelve lamps, then one moved" "$GR" "${IN[@]}" "$TMP/twelve.script" -o "$TMP/twelve" -v
n=$(sed -n "/frame 0 'twelve'/,\$p" "$TMP/stderr" | grep -c 'light [0-9]*: rows')
check "... the move recomputes the direct light of one lamp ($n)" [ "$n" = 1 ]
# -v counts the photons after the entry points that carry light: only paths
# from lit entry points do. Twelve lamps under the ceiling light most of the
# box; a 4-degree spot on the floor lights a patch of it.
lit() { sed -n 's/.* \([0-9]*\) of \([0-9]*\) photons after the entry points carry light.*/\1 \2/p' "$1" | head -1; }
read -r l12 n12 <<<"$(lit "$TMP/stderr")"
printf 'resolution 16 16\ncamera position 0.278 0.273 -0.8 target 0.278 0.273 0 up 0 1 0 fov 39.3076\n%s\n%s\nframe spot\n' \
  'light ceiling off' 'light s spot position 0.278 0.5 0.28 direction 0 -1 0 intensity 1 outer 4 inner 3' >"$TMP/spot.script"
expect_success "a narrow spot, -v" "$GR" "${IN[@]}" "$TMP/spot.script" -o "$TMP/spot" -v
read -r ls ns <<<"$(lit "$TMP/stderr")"
check "... twelve lamps: $l12 of $n12 photons carry light, over 30%" \
  awk -v a="$l12" -v n="$n12" 'BEGIN { exit !(n > 0 && a <= n && a > 0.3 * n) }'
check "... the spot: $ls of $ns, under a tenth of the lamps' share and not none" \
  awk -v a="$ls" -v n="$ns" -v b="$l12" -v m="$n12" 'BEGIN { exit !(n == m && a > 0 && a < 0.1 * b) }'
# Every light is traced at strength 1 and white and scaled: dimming or tinting
# a lamp retraces nothing, and the frame is the lamp's light scaled exactly
# (the lamp alone: twice the intensity is twice every pixel, direct and indirect).
{
  printf 'resolution 32 32\ncamera position 0.278 0.273 -0.8 target 0.278 0.273 0 up 0 1 0 fov 39.3076\n'
  printf 'light ceiling off\nlight l point position 0.2 0.40 0.2795 intensity 0.5\nframe half\n'
  printf 'light l point position 0.2 0.40 0.2795 intensity 1 color 1 0.5 0.25\nframe tinted\n'
  printf 'light l point position 0.2 0.40 0.2795 intensity 1\nframe one\n'
} >"$TMP/dim.script"
expect_success "a lamp dimmed and tinted" "$GR" "${IN[@]}" "$TMP/dim.script" -o "$TMP/dim" -v
n=$(sed -n "/frame 0 'half'/,\$p" "$TMP/stderr" | grep -c 'light [0-9]*: rows')
check "... the dimmed and tinted frames retrace no direct light ($n)" [ "$n" = 0 ]
"$GC" diff "$TMP/dim/half.exr" "$TMP/dim/one.exr" >"$TMP/stdout" 2>/dev/null
r=$(awk -v a="$(val mean_a)" -v b="$(val mean_ref)" 'BEGIN { if (a > 0) printf "%.7f", b / a }')
check "... twice the intensity is twice the light (mean ratio $r)" \
  awk -v r="$r" 'BEGIN { exit !(r != "" && r > 1.99999 && r < 2.00001) }'
expect_success "--frames lamp" "$GR" "${IN[@]}" "$TMP/v.script" -o "$TMP/fn" --frames lamp -q
check "--frames lamp writes lamp.exr only" [ "$(ls "$TMP/fn")" = lamp.exr ]
expect_success "--frames 3 (an index)" "$GR" "${IN[@]}" "$TMP/v.script" -o "$TMP/f3" --frames 3 -q
check "--frames 3 writes blue-wall.exr only" [ "$(ls "$TMP/f3")" = blue-wall.exr ]
# Alone, frame 3 recomputes every reflectance from the detail section; in the
# full run only the left wall's were recomputed, the others came from RGB9E5.
"$GC" diff "$TMP/f3/blue-wall.exr" "$O/blue-wall.exr" >"$TMP/stdout" 2>/dev/null
check "a material change in sequence equals a full recompute (nrmse=$(val nrmse) < 0.01)" lt "$(val nrmse)" 0.01
expect_success "--frames blue-wall (a name with a dash)" "$GR" "${IN[@]}" "$TMP/v.script" -o "$TMP/fd" --frames blue-wall -q
check "--frames blue-wall writes blue-wall.exr only" [ "$(ls "$TMP/fd" 2>/dev/null)" = blue-wall.exr ]

# ---- refusals before any rendering: exit code, message, no output ------------------------------------
R=$TMP/refused
printf 'resolution 8 8\nlight lamp point position 0 0 0 intensity bright\nframe a\n' >"$TMP/bad.script"
expect_exit 3 "a script syntax error (exit 3)" "$GR" "${IN[@]}" "$TMP/bad.script" -o "$R"
expect_stderr "bad\.script:2:43: expected a number after 'intensity', got 'bright'" "file:line:column of the error"
printf 'material Nope roughness 1\nframe a\n' >"$TMP/foreign.script"
expect_exit 3 "a script naming a material the scene lacks (exit 3)" "$GR" "${IN[@]}" "$TMP/foreign.script" -o "$R"
expect_stderr "foreign\.script:1:10: .*got 'Nope'" "the scene check gives file:line:column"
printf 'resolution 8 8\nframe first\ncamera position 0.278 0.273 -0.8 target 0.278 0.273 0\nframe second\n' \
  >"$TMP/nocam.script"
expect_exit 3 "a frame without a camera (exit 3)" "$GR" "${IN[@]}" "$TMP/nocam.script" -o "$R"
expect_stderr "nocam\.script: frame 'first' has no camera" "the script and the frame are named"
expect_success "... but a range that leaves it out renders" "$GR" "${IN[@]}" "$TMP/nocam.script" -o "$TMP/nc" --frames second -q

"$GP" "$C" -o "$TMP/c2.gip" --photons 20000 -s 2 -q
expect_exit 3 "a .gih built from another .gip (exit 3)" "$GR" "$C" "$TMP/c2.gip" "$TMP/c.gih" "$TMP/v.script" -o "$R"
expect_stderr "c\.gih: section 'META': made from gip hash [0-9a-f]+, but the gip given has [0-9a-f]+ \(re-run gi-hvds\)" \
  "the message names the .gih and the gip"
sed 's/{"name":"TallBlock","mesh":6}/{"name":"TallBlock","mesh":6,"translation":[0.001,0,0]}/' "$C" >"$TMP/d.gltf"
"$GP" "$TMP/d.gltf" -o "$TMP/d.gip" --photons 20000 -q
"$GH" "$TMP/d.gltf" "$TMP/d.gip" -o "$TMP/d.gih" --gather-rays 4 --r-max 0.1 -q
expect_exit 3 "a .gip of another scene (exit 3)" "$GR" "$C" "$TMP/d.gip" "$TMP/c.gih" "$TMP/v.script" -o "$R"
expect_stderr "d\.gip: section 'META': made from scene hash" "the .gip is named"
expect_exit 3 "a .gih of another scene (exit 3)" "$GR" "$C" "$TMP/c.gip" "$TMP/d.gih" "$TMP/v.script" -o "$R"
expect_stderr "d\.gih: section 'META': made from scene hash" "the .gih is named"
expect_exit 3 "a .gip and .gih of another scene (exit 3)" "$GR" "$C" "$TMP/d.gip" "$TMP/d.gih" "$TMP/v.script" -o "$R"
head -c 50000 "$TMP/c.gih" >"$TMP/trunc.gih"
expect_exit 3 "a truncated .gih (exit 3)" "$GR" "$C" "$TMP/c.gip" "$TMP/trunc.gih" "$TMP/v.script" -o "$R"
expect_stderr "trunc\.gih: truncated" "the truncated .gih is named"

expect_exit 4 "a missing scene (exit 4)" "$GR" "$TMP/none.gltf" "$TMP/c.gip" "$TMP/c.gih" "$TMP/v.script" -o "$R"
expect_stderr "none\.gltf" "the missing scene is named"
expect_exit 4 "a missing .gip (exit 4)" "$GR" "$C" "$TMP/none.gip" "$TMP/c.gih" "$TMP/v.script" -o "$R"
expect_stderr "none\.gip" "the missing .gip is named"
expect_exit 4 "a missing .gih (exit 4)" "$GR" "$C" "$TMP/c.gip" "$TMP/none.gih" "$TMP/v.script" -o "$R"
expect_stderr "none\.gih" "the missing .gih is named"
expect_exit 4 "a missing script (exit 4)" "$GR" "${IN[@]}" "$TMP/none.script" -o "$R"
expect_stderr "none\.script: cannot open" "the missing script is named"
expect_exit 4 "an OUTDIR whose parent is missing (exit 4)" "$GR" "${IN[@]}" "$TMP/v.script" -o "$TMP/no/such"
expect_stderr "no/such: cannot create the output directory" "the output directory is named"
printf 'not a directory\n' > "$TMP/afile"
expect_exit 2 "an OUTDIR that is a file (exit 2, before any rendering)" "$GR" "${IN[@]}" "$TMP/v.script" -o "$TMP/afile"
expect_stderr "afile: expected an output directory, got a file" "the file is named"
[ "$(cat "$TMP/afile")" = "not a directory" ] && ok "the file is left as it was" || not_ok "the file was changed"

expect_exit 2 "an unknown option (exit 2)" "$GR" "${IN[@]}" "$TMP/v.script" -o "$R" --bogus
expect_exit 2 "missing -o (exit 2)" "$GR" "${IN[@]}" "$TMP/v.script"
expect_stderr "missing -o" "missing -o is explained"
expect_exit 2 "three positional arguments (exit 2)" "$GR" "${IN[@]}" -o "$R"
expect_stderr "got 3 arguments" "the argument count is given"
expect_exit 2 "--ss 0 (exit 2)" "$GR" "${IN[@]}" "$TMP/v.script" -o "$R" --ss 0
expect_exit 2 "--area-samples x (exit 2)" "$GR" "${IN[@]}" "$TMP/v.script" -o "$R" --area-samples x
expect_exit 2 "--exposure 100 (exit 2)" "$GR" "${IN[@]}" "$TMP/v.script" -o "$R" --exposure 100
expect_exit 2 "--interp cubic (exit 2)" "$GR" "${IN[@]}" "$TMP/v.script" -o "$R" --interp cubic
expect_exit 2 "--frames with an unknown name (exit 2)" "$GR" "${IN[@]}" "$TMP/v.script" -o "$R" --frames nosuch
expect_stderr "no frame 'nosuch'" "the unknown frame is named"
expect_exit 2 "--frames past the last frame (exit 2)" "$GR" "${IN[@]}" "$TMP/v.script" -o "$R" --frames 1-4
expect_exit 2 "--frames backwards (exit 2)" "$GR" "${IN[@]}" "$TMP/v.script" -o "$R" --frames 2-1
check "no refusal created OUTDIR" test ! -e "$R"
check "no refusal created the missing parent" test ! -e "$TMP/no"
check "no temporary file left anywhere" test -z "$(find "$TMP" -name '*.tmp.*' -print -quit)"

# ---- against the path-traced reference ----------------------------------------------------------
# A loose smoke bound: nrmse < 0.15 and mean brightness within 10% at 32x32,
# 4096 spp (reference noise about 0.02). --ss 4 makes the relight average over
# each pixel, as the path tracer does: with pixel centres only, the edges of a
# 32x32 image alone give nrmse near 0.2. 'base' uses the reflectances stored in
# the .gip; 'blue' recomputes the left wall's from the detail section.
cat >"$TMP/r.script" <<'EOF'
resolution 32 32
camera position 0.278 0.273 -0.8 target 0.278 0.273 0 up 0 1 0 fov 39.3076
frame base
material LeftWall basecolor 0.1 0.2 0.6
frame blue
EOF
expect_success "relight 32x32 --ss 4" "$GR" "${IN[@]}" "$TMP/r.script" -o "$TMP/rl" --ss 4 -q
for f in base blue; do
  expect_success "$f: reference (gi-compare render, 4096 spp)" \
    "$GC" render "$C" "$TMP/r.script" --frame $f -o "$TMP/ref_$f.exr" --spp 4096 -j 2 -q
  expect_success "$f: gi-compare diff" "$GC" diff "$TMP/rl/$f.exr" "$TMP/ref_$f.exr"
  check "$f: nrmse $(val nrmse) < 0.15 (loose smoke bound)" lt "$(val nrmse)" 0.15
  ratio=$(awk -v a="$(val mean_a)" -v b="$(val mean_ref)" 'BEGIN { if (b > 0) printf "%.4f", a / b }')
  check "$f: mean $(val mean_a) vs reference $(val mean_ref) cd/m^2 within 10% (ratio $ratio)" \
    awk -v r="$ratio" 'BEGIN { exit !(r != "" && r > 0.9 && r < 1.1) }'
done
finish
