#!/usr/bin/env bash
# t134-relight-shadow-edge-sliver: a ledge along a wall (mkledge.py) under a high sun, seen
# from 2 m so that its 4 cm top is a strip under half a pixel tall between the wall above
# and the ledge's front: no centre sample sees the top, so its pixels are no edge pixels,
# but the ledge's shadow on the wall below makes them shadow-edge pixels. Their camera rays
# that find the top shade the top (facing the sun, cos 0.99) rather than the wall's plane
# extended over it (cos 0.15): the direct light was 0.108 nrmse against 512 spp, 0.077
# now (the same at two other views and suns: 0.057 -> 0.041, 0.122 -> 0.088).
. "$(dirname "$0")/lib.sh"
command -v python3 >/dev/null || { echo "ok 1 # skip python3 missing"; exit 0; }
S=$TMP/ledge.gltf
python3 "$(dirname "$0")/mkledge.py" "$S" || { not_ok "writing the ledge"; finish; }
cat >"$TMP/v.script" <<'SCRIPT'
resolution 64 48
camera position 2 2 0.3 target 0 1 0 up 0 1 0 fov 50
light sun directional direction -0.15 -1 0.05 illuminance 1000
frame ledge
SCRIPT
direct_vs_reference "$S" "$TMP/v.script" ledge 512
e=$nrmse
check "direct light within nrmse 0.09 of the reference ($e)" awk -v a="$e" 'BEGIN { exit !(a != "" && a + 0 < 0.09) }'
finish
