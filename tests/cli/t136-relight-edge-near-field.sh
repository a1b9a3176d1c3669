#!/usr/bin/env bash
# t136-relight-edge-near-field: a stepped moulding (mkstairs.py, 2 cm steps) under a sun, seen
# from 3 m at 64 x 48, where a step is about a pixel. The edge pixels' samples on a riser or a
# tread that no centre sample sees take the near field of the nearest centre sample on their
# surface in the 3 x 3 pixels around, or with none the points' whole irradiance (the points
# give up their near field, which the pixels add back; such a sample got nothing back and was
# too dark: on this view the 30 pixels it changes held a squared error of 486 against a
# 2048-spp reference, 165 now; docs/journal.md, "Edge samples and the near field"). Checks that both
# ways are taken and that the indirect light stays within nrmse 0.17 of a 1024-spp reference
# (0.150 on 2026-12-06).
. "$(dirname "$0")/lib.sh"
command -v python3 >/dev/null || { echo "ok 1 # skip python3 missing"; exit 0; }
S=$TMP/stairs.gltf
python3 "$(dirname "$0")/mkstairs.py" "$S" || { not_ok "writing the moulding"; finish; }
cat >"$TMP/v.script" <<'SCRIPT'
resolution 64 48
camera position 3 1.6 0.3 target 0.1 0.8 0 up 0 1 0 fov 20
light sun directional direction -0.3 -1 0.1 illuminance 1000
frame stairs
SCRIPT
expect_success "precompute" gi-precompute -q "$S" -o "$TMP/s.gip" --photons 200000
expect_success "hvds" gi-hvds -q "$S" "$TMP/s.gip" -o "$TMP/s.gih"
expect_success "relight, indirect light" gi-relight -v "$S" "$TMP/s.gip" "$TMP/s.gih" "$TMP/v.script" -o "$TMP/out" \
  --only indirect
line=$(grep "edge samples of their own" "$TMP/stderr")
nb=$(echo "$line" | sed -n 's/.*, \([0-9]*\) take a neighbour.*/\1/p')
all=$(echo "$line" | sed -n "s/.*, \([0-9]*\) the points' whole.*/\1/p")
check "some edge samples take a neighbour's near field ($nb)" awk -v a="$nb" 'BEGIN { exit !(a != "" && a + 0 > 0) }'
check "some take the points' whole irradiance ($all)" awk -v a="$all" 'BEGIN { exit !(a != "" && a + 0 > 0) }'
expect_success "reference, indirect light, 1024 spp" gi-compare render -q "$S" "$TMP/v.script" --frame stairs \
  --spp 1024 --min-bounces 1 -o "$TMP/ref.exr"
e=$(gi-compare diff "$TMP/out/stairs.exr" "$TMP/ref.exr" | awk -F= '$1 == "nrmse" { print $2 }')
check "indirect light within nrmse 0.17 of the reference ($e)" awk -v a="$e" 'BEGIN { exit !(a != "" && a + 0 < 0.17) }'
finish
