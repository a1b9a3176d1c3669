#!/usr/bin/env bash
# t139-relight-textured-moulding: three mouldings on a wall (mkmoulding.py), each a
# half-cylinder whose texture is light on its upper half and dark on its lower, like
# Sponza's, under a sun from above, at 64 x 48 (a moulding ~2.4 pixels tall). Their pixels
# are edge pixels (the moulding meets the wall at a crease), and within one the light and
# the texture fall together from the moulding's top to its underside. An edge sample on
# the centre's surface took the centre's texel, its whole pixel's average, so the pixel
# summed light x average texel where the path tracer sums light x texel: against 512 spp
# the direct light read 0.0237 nrmse, the whole frame 0.0300. Each such sample now filters
# its own texel: 0.0095 and 0.0214.
. "$(dirname "$0")/lib.sh"
command -v python3 >/dev/null || { echo "ok 1 # skip python3 missing"; exit 0; }
S=$TMP/moulding.gltf
python3 "$(dirname "$0")/mkmoulding.py" "$S" || { not_ok "writing the mouldings"; finish; }
cat >"$TMP/v.script" <<'SCRIPT'
resolution 64 48
camera position 0.3 1.6 3.5 target 0 1.5 0 up 0 1 0 fov 50
light sun directional direction 0.1 -1 -0.6 illuminance 1000
frame m
SCRIPT
direct_vs_reference "$S" "$TMP/v.script" m 512
e=$nrmse
check "direct light within nrmse 0.015 of the reference ($e)" awk -v a="$e" 'BEGIN { exit !(a != "" && a + 0 < 0.015) }'
# the whole frame: the edge samples' indirect light takes their own texels too
expect_success "relight, whole frame" gi-relight -q "$S" "$TMP/d.gip" "$TMP/d.gih" "$TMP/v.script" -o "$TMP/all"
expect_success "reference, 512 spp" gi-compare render -q "$S" "$TMP/v.script" --spp 512 -o "$TMP/ref.exr"
e=$(gi-compare diff "$TMP/all/m.exr" "$TMP/ref.exr" | awk -F= '$1 == "nrmse" { print $2 }')
check "whole frame within nrmse 0.026 of the reference ($e)" awk -v a="$e" 'BEGIN { exit !(a != "" && a + 0 < 0.026) }'
finish
