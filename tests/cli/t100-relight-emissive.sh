#!/usr/bin/env bash
# t100-relight-emissive: a closed room lit only by an emissive glTF surface
# (a panel under the ceiling, KHR_materials_emissive_strength) and a block
# that shadows the floor. gi-relight must light the scene with it, as the
# path tracer does: within nrmse 0.08 of a 512-spp reference at 48 x 36, for
# the panel as loaded and after a script dims and tints its emission.
. "$(dirname "$0")/lib.sh"
command -v python3 >/dev/null || { echo "ok 1 # skip python3 missing"; exit 0; }
S=$TMP/room.gltf
python3 "$(dirname "$0")/mkroom.py" "$S" || { not_ok "writing the room"; finish; }
cat >"$TMP/v.script" <<'SCRIPT'
resolution 48 36
camera position 2.7 1.4 0.2 target 1.0 0.8 2.4 up 0 1 0 fov 65
frame panel
material panel emission 150 110 70
frame warm
SCRIPT
expect_success "precompute" gi-precompute -q "$S" -o "$TMP/r.gip" --photons 200000
expect_success "hvds" gi-hvds -q "$S" "$TMP/r.gip" -o "$TMP/r.gih"
expect_success "relight" gi-relight -q "$S" "$TMP/r.gip" "$TMP/r.gih" "$TMP/v.script" -o "$TMP/out"
for f in panel warm; do
  expect_success "reference '$f', 512 spp" gi-compare render -q "$S" "$TMP/v.script" --frame $f --spp 512 -o "$TMP/ref-$f.exr"
  gi-compare diff "$TMP/out/$f.exr" "$TMP/ref-$f.exr" >"$TMP/d" 2>&1
  e=$(awk -F= '$1 == "nrmse" { print $2 }' "$TMP/d")
  ma=$(awk -F= '$1 == "mean_a" { print $2 }' "$TMP/d") mr=$(awk -F= '$1 == "mean_ref" { print $2 }' "$TMP/d")
  check "'$f': within nrmse 0.08 of the reference (nrmse $e; mean $ma against $mr cd/m^2)" \
    awk -v a="$e" 'BEGIN { exit !(a != "" && a + 0 < 0.08) }'
done
finish
