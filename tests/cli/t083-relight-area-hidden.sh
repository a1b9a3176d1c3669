#!/usr/bin/env bash
# t083-relight-area-hidden: an area light hidden from the camera, seen edge-on.
# A 0.4 m x 4 mm strip 1 cm above the Cornell box's ceiling, facing down, is
# seen from the camera at 15 degrees: it projects to a sliver about a tenth
# of a pixel high, which the 4 x 4 camera rays of most pixels on its row
# miss. Such pixels used to take the sliver's light unblocked (a row of
# ~1000 cd/m2 in a frame of mean ~3; on Sponza, nrmse 2.0); now rays through
# the sliver itself find the ceiling in front. The frame must match the path
# tracer within nrmse 0.1 (its 256-spp noise is ~0.03), and no pixel may
# differ from it by 10 cd/m2 (the strip's pixels took ~1000).
. "$(dirname "$0")/lib.sh"
skip_under_sanitizers
S=$TMP/cornell.gltf
"$BUILD/tools/mkcornell" "$S" 2>/dev/null
cat >"$TMP/v.script" <<'SCRIPT'
resolution 64 64
camera position 0.278 0.273 -0.8 target 0.278 0.273 0 up 0 1 0 fov 39.3076
light strip area center 0.278 0.5588 0.28 u 0.2 0 0 v 0 0 0.002 luminance 10000
frame hidden-strip
SCRIPT
expect_success "precompute" gi-precompute -q "$S" -o "$TMP/c.gip" --photons 200000
expect_success "hvds" gi-hvds -q "$S" "$TMP/c.gip" -o "$TMP/c.gih"
expect_success "relight" gi-relight -q "$S" "$TMP/c.gip" "$TMP/c.gih" "$TMP/v.script" -o "$TMP/out"
if gi-compare render -q "$S" "$TMP/v.script" --frame hidden-strip --spp 256 -o "$TMP/ref.exr"; then
  gi-compare diff "$TMP/out/hidden-strip.exr" "$TMP/ref.exr" --tolerance 0.1 >"$TMP/d.txt" 2>&1; rc=$?
  e=$(awk -F= '$1 == "nrmse" { print $2 }' "$TMP/d.txt")
  if [ $rc -eq 0 ]; then ok "hidden strip: nrmse $e <= 0.1"; else not_ok "hidden strip: nrmse $e > 0.1 (exit $rc)"; fi
  mx=$(awk -F= '$1 == "max_abs" { print $2 }' "$TMP/d.txt")
  check "largest pixel difference $mx cd/m2 < 10" awk -v a="$mx" 'BEGIN { exit !(a != "" && a < 10) }'
else
  not_ok "reference"
fi
finish
