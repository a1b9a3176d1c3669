#!/usr/bin/env bash
# t094-relight-hard-spot: a spot whose inner and outer cone angles are equal
# throws a hard-edged circle onto the Cornell box's floor (64 x 64). The
# pixels on the circle's edge used to take their centre's value, lit or not
# (Sponza, 160 x 120: nrmse 1.36 against 256 spp, 97% of its square on the
# circle). A pixel outside the cone that faces the spot, beside one inside
# it (lit or shadowed), is now a shadow-edge pixel like any other. The
# direct part must be within nrmse 0.1 of the path tracer's (measured
# 0.068; before, 0.410).
. "$(dirname "$0")/lib.sh"
skip_under_sanitizers
S=$TMP/cornell.gltf
"$BUILD/tools/mkcornell" "$S" 2>/dev/null
cat >"$TMP/v.script" <<'SCRIPT'
resolution 64 64
camera position 0.278 0.273 -0.8 target 0.278 0.273 0 up 0 1 0 fov 39.3076
light ceiling off
light spot spot position 0.2 0.54 0.25 direction 0.1 -1 0.05 intensity 20 inner 25 outer 25
frame hard-spot
SCRIPT
expect_success "precompute" gi-precompute -q "$S" -o "$TMP/c.gip" --photons 100000
expect_success "hvds" gi-hvds -q "$S" "$TMP/c.gip" -o "$TMP/c.gih"
expect_success "relight, direct part" gi-relight -q "$S" "$TMP/c.gip" "$TMP/c.gih" "$TMP/v.script" -o "$TMP/out" --only direct
expect_success "reference, 1024 spp" gi-compare render -q "$S" "$TMP/v.script" --frame hard-spot --spp 1024 \
  --max-bounces 0 -o "$TMP/ref.exr"
gi-compare diff "$TMP/out/hard-spot.exr" "$TMP/ref.exr" >"$TMP/d" 2>&1
e=$(awk -F= '$1 == "nrmse" { print $2 }' "$TMP/d")
check "hard spot, direct part: nrmse $e < 0.1" awk -v a="$e" 'BEGIN { exit !(a != "" && a + 0 < 0.1) }'
finish
