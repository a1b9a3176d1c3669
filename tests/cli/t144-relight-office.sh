#!/usr/bin/env bash
# t144-relight-office: the relight against the path tracer on a scene none of
# the defaults was tuned on (tests/cli/mkoffice.py, written 2026-12-08): an
# office whose window opening lets a sun in, then a spot over the desk and a
# lamp, a camera move, the oak floor made glossy and the steel cabinet
# sharper, and the sun back on with both lamps. 96 x 72 (the defaults' 7 x 7
# edge samples), against 1024-spp references.
#
# Measured 2026-12-08 (nrmse net of the references' own noise, and at
# 320 x 240 against 1024 spp in brackets): o1-sun 0.111 (0.087), o2-sun-moved
# 0.043 (0.031), o3-lamps 0.031 (0.025), o4-camera 0.024 (0.018),
# o5-materials 0.033 (0.027), o6-all 0.108 (0.040). The two frames with the
# sun in view of the camera's sunlit patches are the worst: their error is
# mostly at the edges of patches 20-600 times the frame's mean luminance
# (the window's sill seen edge-on, the patch's borders on the floor), where
# the 7 x 7 or 9 x 9 samples of an edge pixel leave a coverage error of a few
# percent of the patch. The bounds are those figures with a margin: a guard
# for the general case, not a target met.
. "$(dirname "$0")/lib.sh"
command -v python3 >/dev/null || { echo "ok 1 # skip python3 missing"; exit 0; }
skip_under_sanitizers
S=$TMP/office.gltf
python3 "$(dirname "$0")/mkoffice.py" "$S" || { not_ok "writing the office"; finish; }
cat >"$TMP/o.script" <<'SCRIPT'
resolution 96 72
camera position 5.2 1.6 4.6 target 2.5 0.9 1.5 up 0 1 0 fov 65
light sun directional direction -0.3 -0.6 0.75 illuminance 60000 color 1 0.95 0.88
frame o1-sun
light sun directional direction 0.25 -0.5 0.83 illuminance 60000 color 1 0.95 0.88
frame o2-sun-moved
light sun off
light desk spot position 2.3 2.6 2.2 direction 0 -1 0 intensity 800 outer 35 inner 20 color 1 0.9 0.75
light lamp point position 0.8 2.2 1.0 intensity 120 color 1 0.85 0.7
frame o3-lamps
camera position 0.8 1.5 4.7 target 3.5 0.8 1.8 up 0 1 0 fov 60
frame o4-camera
material oak roughness 0.25 metallic 0
material steel roughness 0.2
frame o5-materials
light sun directional direction -0.3 -0.6 0.75 illuminance 60000 color 1 0.95 0.88
frame o6-all
SCRIPT
expect_success "precompute" gi-precompute -q "$S" -o "$TMP/o.gip" --photons 300000
expect_success "hvds" gi-hvds -q "$S" "$TMP/o.gip" -o "$TMP/o.gih"
expect_success "relight" gi-relight -q "$S" "$TMP/o.gip" "$TMP/o.gih" "$TMP/o.script" -o "$TMP/out"
for f in o1-sun:0.15 o2-sun-moved:0.06 o3-lamps:0.05 o4-camera:0.04 o5-materials:0.05 o6-all:0.15; do
  n=${f%%:*} tol=${f#*:}
  expect_success "reference '$n', 1024 spp" gi-compare render -q "$S" "$TMP/o.script" --frame "$n" --spp 1024 \
    -o "$TMP/ref-$n.exr"
  e=$(gi-compare diff "$TMP/out/$n.exr" "$TMP/ref-$n.exr" 2>/dev/null | awk -F= '$1 == "nrmse_excess" { print $2 }')
  check "'$n': within $tol of the reference net of its noise (nrmse_excess $e)" \
    awk -v a="$e" -v t="$tol" 'BEGIN { exit !(a != "" && a + 0 <= t + 0) }'
done
finish
