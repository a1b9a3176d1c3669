#!/usr/bin/env bash
# t082-relight-area-analytic: a large ceiling panel (0.4 x 0.4 m) in the
# Cornell box, as diffuse and with a glossy floor, and a small panel on a wall.
# Sampled with 16 jittered points per pixel, the walls next to the large panel
# were grainy (nrmse 0.045 at 64 x 64 against 4096 spp); the relight now takes
# a rectangle's diffuse light from Lambert's formula times the share of the
# samples that see it (gi_area_light_form), and every frame must be within
# 0.025. Skipped under the sanitizers, where the references would take too
# long; test_pt_analytic checks the formula itself there.
. "$(dirname "$0")/lib.sh"
skip_under_sanitizers
S=$TMP/cornell.gltf
"$BUILD/tools/mkcornell" "$S" 2>/dev/null
cat >"$TMP/v.script" <<'SCRIPT'
resolution 64 64
camera position 0.278 0.273 -0.8 target 0.278 0.273 0 up 0 1 0 fov 39.3076
light ceiling off
light big area center 0.278 0.5478 0.28 u 0.2 0 0 v 0 0 0.2 luminance 20
frame big-panel
material Floor roughness 0.3
frame glossy-floor
light big off
light wall area center 0.002 0.30 0.30 u 0 0.05 0 v 0 0 0.05 luminance 100
frame wall-panel
SCRIPT
expect_success "precompute" gi-precompute -q "$S" -o "$TMP/c.gip"
expect_success "hvds" gi-hvds -q "$S" "$TMP/c.gip" -o "$TMP/c.gih"
expect_success "relight" gi-relight -q "$S" "$TMP/c.gip" "$TMP/c.gih" "$TMP/v.script" -o "$TMP/out"
for f in big-panel glossy-floor wall-panel; do
  gi-compare render -q "$S" "$TMP/v.script" --frame "$f" --spp 4096 -o "$TMP/ref-$f.exr" ||
    { not_ok "reference of $f"; continue; }
  gi-compare diff "$TMP/out/$f.exr" "$TMP/ref-$f.exr" --tolerance 0.025 >"$TMP/d.txt" 2>&1; rc=$?
  e=$(awk -F= '$1 == "nrmse" { print $2 }' "$TMP/d.txt")
  if [ $rc -eq 0 ]; then ok "frame $f: nrmse $e <= 0.025"
  else not_ok "frame $f: nrmse $e > 0.025 (exit $rc)"; fi
done
finish
