#!/usr/bin/env bash
# t137-relight-terminator: five 24-sided columns (mkprisms.py) under a low sun, seen from
# 4 m at 64 x 48 so that each side is about a pixel wide. Where the sun's terminator runs
# down a column, a lit side meets one that faces away from the sun; their normals are 15
# degrees apart, under the crease threshold, so neither pixel is an edge pixel, and before
# neither was a shadow-edge pixel either (the one facing away sends no shadow ray): each
# kept its centre's light. Now such pixels are shadow edges: the direct light went 0.104
# -> 0.092 nrmse against 512 spp; under a spot instead of the sun, 0.133 -> 0.118.
. "$(dirname "$0")/lib.sh"
command -v python3 >/dev/null || { echo "ok 1 # skip python3 missing"; exit 0; }
S=$TMP/prisms.gltf
python3 "$(dirname "$0")/mkprisms.py" "$S" || { not_ok "writing the columns"; finish; }
cat >"$TMP/v.script" <<'SCRIPT'
resolution 64 48
camera position 4 1 0.3 target 0 1 0 up 0 1 0 fov 50
light sun directional direction -0.2 -0.4 -1 illuminance 1000
frame prisms
SCRIPT
direct_vs_reference "$S" "$TMP/v.script" prisms 512
e=$nrmse
check "direct light within nrmse 0.098 of the reference ($e)" awk -v a="$e" 'BEGIN { exit !(a != "" && a + 0 < 0.098) }'
cat >"$TMP/s.script" <<'SCRIPT'
resolution 64 48
camera position 4 1 0.3 target 0 1 0 up 0 1 0 fov 50
light key spot position 1.5 2.5 6 direction -0.2 -0.3 -1 intensity 4000 inner 30 outer 40
frame spot
SCRIPT
direct_vs_reference "$S" "$TMP/s.script" spot 512
e=$nrmse
check "under a spot, direct light within nrmse 0.126 of the reference ($e)" \
  awk -v a="$e" 'BEGIN { exit !(a != "" && a + 0 < 0.126) }'
finish
