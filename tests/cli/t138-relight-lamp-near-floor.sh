#!/usr/bin/env bash
# t138-relight-lamp-near-floor: a 10 cd lamp 5 cm above a floor, seen from 3 m at 64 x 48
# (7 cm a pixel). Its irradiance falls as h / r^3 across the pixel under it, so that
# pixel's centre sample stands for none of it, and no edge marks the pixel. A lit pixel
# whose centre's irradiance stands out from its neighbours' mean now takes 24 more points
# of the surface: the direct light went 4.25 -> 0.119 nrmse against 512 spp (the pixel
# under the lamp 201 cd/m2 off -> 4.9).
. "$(dirname "$0")/lib.sh"
command -v python3 >/dev/null || { echo "ok 1 # skip python3 missing"; exit 0; }
S=$TMP/floor.gltf
python3 -c "import sys; sys.path.insert(0, sys.argv[1]); from gltfquads import write_quads
write_quads(sys.argv[2], [[(-2, 0, -2), (-2, 0, 2), (2, 0, 2), (2, 0, -2)]])" "$(dirname "$0")" "$S" ||
  { not_ok "writing the floor"; finish; }
cat >"$TMP/v.script" <<'SCRIPT'
resolution 64 48
camera position 0 3 0.01 target 0 0 0 up 0 0 -1 fov 60
light lamp point position 0.02 0.05 -0.03 intensity 10
frame lamp
SCRIPT
direct_vs_reference "$S" "$TMP/v.script" lamp 512
e=$nrmse
check "direct light within nrmse 0.3 of the reference ($e)" awk -v a="$e" 'BEGIN { exit !(a != "" && a + 0 < 0.3) }'
finish
