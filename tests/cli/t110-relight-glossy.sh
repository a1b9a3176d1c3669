#!/usr/bin/env bash
# t110-relight-glossy: glossy reflection of indirect light. A room with a
# metal floor (roughness 0.5, then 0.3 by a script change), a red and a blue
# wall and an emissive ceiling panel: the floor reflects the walls' colours
# towards the camera. Against 512-spp references at 64 x 48 the relight must
# be within nrmse 0.115 (roughness 0.5) and 0.195 (0.3): the pixels' own
# glossy gathers give 0.104 and 0.181, where the gathering points' linear fit
# gave 0.126 and 0.207. Glossy lobes taken as diffuse (the relight before
# GDIR) measured 0.33 and 0.48, and the lobe's albedo without the directional
# fit 0.20 and 0.32 (at 96 x 72, 1024 spp).
. "$(dirname "$0")/lib.sh"
command -v python3 >/dev/null || { echo "ok 1 # skip python3 missing"; exit 0; }
S=$TMP/room.gltf
python3 "$(dirname "$0")/mkroom.py" "$S" --metal-floor 0.5 || { not_ok "writing the room"; finish; }

cat >"$TMP/v.script" <<'SCRIPT'
resolution 64 48
camera position 2.7 1.6 0.3 target 1.2 0.2 2.0 up 0 1 0 fov 60
material metal roughness 1
frame matte
material metal roughness 0.5
frame rough05
material metal roughness 0.3
frame rough03
material metal roughness 0.33
frame rough033
material metal roughness 0.4
frame rough04
material metal metallic 0 roughness 0.2
frame polished
SCRIPT
expect_success "precompute" gi-precompute -q "$S" -o "$TMP/r.gip" --photons 200000
expect_success "hvds" gi-hvds -q "$S" "$TMP/r.gip" -o "$TMP/r.gih"
expect_success "relight" gi-relight -q "$S" "$TMP/r.gip" "$TMP/r.gih" "$TMP/v.script" -o "$TMP/out" \
  --timings "$TMP/t.csv"
# a material change keeps the view, the first that makes a lobe glossy
# too: the normals' spread glossy lobes need is in the G-buffer from the
# start (it was made again, ~0.4 s on Sponza)
check "material changes do not rasterise again" awk -F, '
  NR == 1 { for (i = 1; i <= NF; i++) c[$i] = i; next }
  $c["changed"] == "materials" { n++; if ($c["t_gbuffer_ms"] + 0 > 0.5) bad++ }
  END { exit !(n == 5 && !bad) }' "$TMP/t.csv"
# a dielectric lobe (ks 0.04) takes the gathering points' linear fit: the
# same image as --glossy-rays 0; with --glossy-min-ks 0 it gathers
expect_success "relight, dielectric without gathers" gi-relight -q "$S" "$TMP/r.gip" "$TMP/r.gih" "$TMP/v.script" \
  -o "$TMP/fit" --glossy-rays 0 --frames polished
expect_success "relight, dielectric gathering" gi-relight -q "$S" "$TMP/r.gip" "$TMP/r.gih" "$TMP/v.script" \
  -o "$TMP/all" --glossy-min-ks 0 --frames polished
d0=$(gi-compare diff "$TMP/out/polished.exr" "$TMP/fit/polished.exr" 2>/dev/null | awk -F= '$1 == "nrmse" { print $2 }')
d1=$(gi-compare diff "$TMP/all/polished.exr" "$TMP/fit/polished.exr" 2>/dev/null | awk -F= '$1 == "nrmse" { print $2 }')
# roughness 0.3 -> 0.33 (Phong exponent 245 -> 165) reuses the rays drawn
# for 0.3, weighted by importance: not the image of a fresh draw, but as near
# to it as two draws are to each other
expect_success "relight, rough033 drawn afresh" gi-relight -q "$S" "$TMP/r.gip" "$TMP/r.gih" "$TMP/v.script" \
  -o "$TMP/fresh" --frames rough033
d2=$(gi-compare diff "$TMP/out/rough033.exr" "$TMP/fresh/rough033.exr" 2>/dev/null | awk -F= '$1 == "nrmse" { print $2 }')
check "a small roughness change reuses the rays (nrmse $d2 from a fresh draw: > 0, < 0.03)" \
  awk -v a="$d2" 'BEGIN { exit !(a != "" && a + 0 > 0 && a + 0 < 0.03) }'
# 0.33 -> 0.4 (exponent 165 -> 76, 0.31 of the 245 drawn for): within the
# mixture's range (0.25 to 6 times), so the same rays again
expect_success "relight, rough04 drawn afresh" gi-relight -q "$S" "$TMP/r.gip" "$TMP/r.gih" "$TMP/v.script" \
  -o "$TMP/fresh" --frames rough04
d4=$(gi-compare diff "$TMP/out/rough04.exr" "$TMP/fresh/rough04.exr" 2>/dev/null | awk -F= '$1 == "nrmse" { print $2 }')
check "0.33 -> 0.4 (0.31 of the exponent drawn for) reuses the rays too (nrmse $d4 from a fresh draw: > 0, < 0.04)" \
  awk -v a="$d4" 'BEGIN { exit !(a != "" && a + 0 > 0 && a + 0 < 0.04) }'
check "a dielectric lobe takes the fit by default (nrmse $d0 from --glossy-rays 0)" \
  awk -v a="$d0" 'BEGIN { exit !(a != "" && a + 0 == 0) }'
check "and gathers with --glossy-min-ks 0 (nrmse $d1, within 0.01 of the fit)" \
  awk -v a="$d1" 'BEGIN { exit !(a != "" && a + 0 > 0 && a + 0 < 0.01) }'
for f in rough05:0.115 rough03:0.195 rough033:0.195; do
  n=${f%%:*} tol=${f#*:}
  expect_success "reference '$n', 512 spp" gi-compare render -q "$S" "$TMP/v.script" --frame $n --spp 512 -o "$TMP/ref-$n.exr"
  e=$(gi-compare diff "$TMP/out/$n.exr" "$TMP/ref-$n.exr" 2>/dev/null | awk -F= '$1 == "nrmse" { print $2 }')
  check "'$n': within nrmse $tol of the reference (nrmse $e)" awk -v a="$e" -v t="$tol" 'BEGIN { exit !(a != "" && a + 0 < t + 0) }'
done
# --glossy-stride 1: every pixel gathers (the default, 2, a quarter of
# them): another image, as near to the reference
expect_success "relight rough03, every pixel gathering" gi-relight -q "$S" "$TMP/r.gip" "$TMP/r.gih" "$TMP/v.script" \
  -o "$TMP/s1" --glossy-stride 1 --frames rough03
d3=$(gi-compare diff "$TMP/s1/rough03.exr" "$TMP/out/rough03.exr" 2>/dev/null | awk -F= '$1 == "nrmse" { print $2 }')
e3=$(gi-compare diff "$TMP/s1/rough03.exr" "$TMP/ref-rough03.exr" 2>/dev/null | awk -F= '$1 == "nrmse" { print $2 }')
check "--glossy-stride 1 gathers at other pixels (nrmse $d3 from the default: > 0, < 0.08)" \
  awk -v a="$d3" 'BEGIN { exit !(a != "" && a + 0 > 0 && a + 0 < 0.08) }'
check "--glossy-stride 1: within nrmse 0.195 of the reference (nrmse $e3)" \
  awk -v a="$e3" 'BEGIN { exit !(a != "" && a + 0 < 0.195) }'
# --ss 2 (four jittered G-buffers): every sample gathers and takes its own
# term (each took sample 0's, and a metal floor reflected nothing)
expect_success "relight rough03 at --ss 2" gi-relight -q "$S" "$TMP/r.gip" "$TMP/r.gih" "$TMP/v.script" \
  -o "$TMP/ss2" --ss 2 --frames rough03
e5=$(gi-compare diff "$TMP/ss2/rough03.exr" "$TMP/ref-rough03.exr" 2>/dev/null | awk -F= '$1 == "nrmse" { print $2 }')
check "--ss 2: within nrmse 0.195 of the reference (nrmse $e5)" \
  awk -v a="$e5" 'BEGIN { exit !(a != "" && a + 0 < 0.195) }'
# a lobe wider than a window twice as wide (roughness 0.7 at 256 x 192)
# gathers on a grid twice as coarse, over 15 x 15 pixels: ~1/16 of its
# pixels gather (1277 of 17797), where roughness 0.3 keeps a quarter; near
# the image of every pixel gathering (0.0110; 0.0063 on the finer grid)
cat >"$TMP/w.script" <<'SCRIPT'
resolution 256 192
camera position 2.7 1.6 0.3 target 1.2 0.2 2.0 up 0 1 0 fov 60
material metal roughness 0.7
frame wide
material metal roughness 0.3
frame sharp
material metal roughness 0.12
frame mirror
SCRIPT
# "N on the grid, L of M others alone": the share of the glossy pixels that gathered
share() { sed -n 's/.*(\([0-9]*\) on the grid, \([0-9]*\) of \([0-9]*\) others alone).*/\1 \2 \3/p' "$1" |
  awk -v k="$2" 'NR == k { printf "%.4f", ($1 + $2) / ($1 + $3) }'; }
expect_success "relight at 256 x 192, -v" gi-relight -v "$S" "$TMP/r.gip" "$TMP/r.gih" "$TMP/w.script" -o "$TMP/w"
cp "$TMP/stderr" "$TMP/w.log"
expect_success "the same, every pixel gathering" gi-relight -q "$S" "$TMP/r.gip" "$TMP/r.gih" "$TMP/w.script" \
  -o "$TMP/w1" --glossy-stride 1 --frames wide
expect_success "the mirror at --glossy-rays 81" gi-relight -v "$S" "$TMP/r.gip" "$TMP/r.gih" "$TMP/w.script" \
  -o "$TMP/w81" --glossy-rays 81 --frames mirror
cp "$TMP/stderr" "$TMP/w81.log"
sw=$(share "$TMP/w.log" 1) ss=$(share "$TMP/w.log" 2)
check "roughness 0.7 gathers on the coarse grid (share $sw of its pixels, < 0.1)" \
  awk -v a="$sw" 'BEGIN { exit !(a != "" && a + 0 > 0 && a + 0 < 0.1) }'
check "roughness 0.3 on the fine grid (share $ss, > 0.2)" awk -v a="$ss" 'BEGIN { exit !(a != "" && a + 0 > 0.2) }'
d5=$(gi-compare diff "$TMP/w/wide.exr" "$TMP/w1/wide.exr" 2>/dev/null | awk -F= '$1 == "nrmse" { print $2 }')
check "the coarse grid's image near every pixel's (nrmse $d5, < 0.03)" \
  awk -v a="$d5" 'BEGIN { exit !(a != "" && a + 0 > 0 && a + 0 < 0.03) }'
# a lobe narrower than the window (roughness 0.12 here; not 0.3) draws 16
# of the 36 rays ("D drawn of R rays"; 36 of 81), and reflects as much
# light as with more rays (the room's small bright patches make per-pixel
# differences large: 0.13 nrmse between 16 and 36 rays, 0.37 against every
# pixel gathering, with 16 or 36 rays alike)
rays() { sed -n 's/.* \([0-9]*\) drawn of \([0-9]*\) rays.*/\1 \2/p' "$1" |
  awk -v k="$2" 'NR == k { if ($1 > 0) printf "%.2f", $2 / $1 }'; }
r2=$(rays "$TMP/w.log" 2) r3=$(rays "$TMP/w.log" 3)
check "roughness 0.3: 36 rays a gather ($r2)" awk -v a="$r2" 'BEGIN { exit !(a == "36.00") }'
check "roughness 0.12: 16 rays a gather ($r3)" awk -v a="$r3" 'BEGIN { exit !(a == "16.00") }'
r81=$(rays "$TMP/w81.log" 1)
check "--glossy-rays 81: 36 rays a gather of the mirror ($r81)" awk -v a="$r81" 'BEGIN { exit !(a == "36.00") }'
m6=$(gi-compare diff "$TMP/w/mirror.exr" "$TMP/w81/mirror.exr" 2>/dev/null |
  awk -F= '$1 == "mean_a" { a = $2 } $1 == "mean_ref" { b = $2 } END { if (b > 0) printf "%.4f", a / b }')
check "the mirror's mean with 16 rays within 1% of 36 rays' (ratio $m6)" \
  awk -v a="$m6" 'BEGIN { exit !(a != "" && a + 0 > 0.99 && a + 0 < 1.01) }'
expect_exit 2 "--glossy-stride 0 is refused" gi-relight -q "$S" "$TMP/r.gip" "$TMP/r.gih" "$TMP/v.script" \
  -o "$TMP/s0" --glossy-stride 0
expect_stderr "glossy-stride.*range" "the message names the option and its range"
finish
