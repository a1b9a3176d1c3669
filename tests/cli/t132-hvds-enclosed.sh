#!/usr/bin/env bash
# t132-hvds-enclosed: a ceiling with a second layer 1 cm behind it, facing the same way and
# listed first (mklayer.py), a face inside other geometry as Sponza's vaults have. gi-hvds
# places no gathering points on it (every probe ray finds the back of the ceiling), so the
# ceiling's pixels do not interpolate its points, which hold no light (before: 162 k points,
# most on the hidden layer, and nrmse 0.039 against the path tracer; now 23 k and 0.013).
. "$(dirname "$0")/lib.sh"
command -v python3 >/dev/null || { echo "ok 1 # skip python3 missing"; exit 0; }
S=$TMP/layer.gltf
python3 "$(dirname "$0")/mklayer.py" "$S" || { not_ok "writing the scene"; finish; }
cat >"$TMP/v.script" <<'SCRIPT'
resolution 64 48
camera position 0 0.4 1.8 target 0 2 -0.6 up 0 1 0 fov 60
light bulb point position 0.3 0.8 -0.2 intensity 100
frame layer
SCRIPT
expect_success "precompute" gi-precompute -q "$S" -o "$TMP/l.gip" --photons 200000
expect_success "hvds" gi-hvds -v "$S" "$TMP/l.gip" -o "$TMP/l.gih"
n=$(sed -n 's/.*candidates: \([0-9]*\) of [0-9]* inside other geometry.*/\1/p' "$TMP/stderr")
check "it dropped the hidden layer's candidates (${n:-none})" awk -v n="$n" 'BEGIN { exit !(n + 0 > 100000) }'
p=$(sed -n 's/.*gathering points: \([0-9]*\) of .*/\1/p' "$TMP/stderr")
check "a few tens of thousands of points, not the hidden layer's many (${p:-none})" \
  awk -v n="$p" 'BEGIN { exit !(n + 0 > 1000 && n + 0 < 60000) }'
expect_success "relight" gi-relight -q "$S" "$TMP/l.gip" "$TMP/l.gih" "$TMP/v.script" -o "$TMP/out"
expect_success "reference, 1024 spp" gi-compare render -q "$S" "$TMP/v.script" --frame layer --spp 1024 -o "$TMP/ref.exr"
e=$(gi-compare diff "$TMP/out/layer.exr" "$TMP/ref.exr" | awk -F= '$1 == "nrmse" { print $2 }')
check "within nrmse 0.025 of the reference ($e)" awk -v a="$e" 'BEGIN { exit !(a != "" && a + 0 < 0.025) }'
finish
