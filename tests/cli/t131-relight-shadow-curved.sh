#!/usr/bin/env bash
# t131-relight-shadow-curved: a board's sun shadow across a trough of 48 flat facets
# (mktrough.py), a shadow's edge on a concave curved face. The pixels beside the edge
# take the sun at points of the real surface: the centre's plane, extended over the pixel,
# lies behind the next facet, which blocked its points' shadow rays (direct light 0.143
# nrmse against the path tracer before, 0.036 with the surface's points, 0.034 with their own
# shading normals).
. "$(dirname "$0")/lib.sh"
command -v python3 >/dev/null || { echo "ok 1 # skip python3 missing"; exit 0; }
S=$TMP/trough.gltf
python3 "$(dirname "$0")/mktrough.py" "$S" || { not_ok "writing the trough"; finish; }
cat >"$TMP/v.script" <<'SCRIPT'
resolution 64 48
camera position 0 3.2 2.6 target 0 0.4 0.9 up 0 1 0 fov 55
light sun directional direction 0.25 -1 0.9 illuminance 1000
frame trough
SCRIPT
direct_vs_reference "$S" "$TMP/v.script" trough 512
e=$nrmse
check "direct light within nrmse 0.07 of the reference ($e)" awk -v a="$e" 'BEGIN { exit !(a != "" && a + 0 < 0.07) }'
finish
