#!/usr/bin/env bash
# t101-relight-emissive-furnace: a closed box whose 192 triangles all emit 10
# nits and reflect about half (mkfurnace.py): inside, the radiance is nearly
# the same everywhere. Its mesh light is too large for the closed form, so
# the relight samples it; with light samples alone, points near the concave
# corners, lit by the faces across at a few centimetres, spiked (direct part
# nrmse 0.096 against 1024 spp, up to 38.6 cd/m2 where the mean is 15.2). The
# relight weighs them against BSDF samples as the path tracer does, and the
# direct part and the whole frame must be within nrmse 0.05 of the path
# tracer (measured 0.024 and 0.024).
. "$(dirname "$0")/lib.sh"
command -v python3 >/dev/null || { echo "ok 1 # skip python3 missing"; exit 0; }
skip_under_sanitizers
S=$TMP/furnace.gltf
python3 "$(dirname "$0")/mkfurnace.py" "$S" 4 10 0.5 || { not_ok "writing the box"; finish; }
cat >"$TMP/v.script" <<'SCRIPT'
resolution 64 48
camera position 1.6 1.5 0.3 target 0.2 0.4 1.8 up 0 1 0 fov 80
frame furnace
SCRIPT
expect_success "precompute" gi-precompute -q "$S" -o "$TMP/f.gip" --photons 200000
expect_success "hvds" gi-hvds -q "$S" "$TMP/f.gip" -o "$TMP/f.gih"
expect_success "relight" gi-relight -q "$S" "$TMP/f.gip" "$TMP/f.gih" "$TMP/v.script" -o "$TMP/all"
expect_success "relight, direct part" gi-relight -q "$S" "$TMP/f.gip" "$TMP/f.gih" "$TMP/v.script" -o "$TMP/direct" --only direct
expect_success "reference, 1024 spp" gi-compare render -q "$S" "$TMP/v.script" --frame furnace --spp 1024 -o "$TMP/ref.exr"
expect_success "reference of the direct part" gi-compare render -q "$S" "$TMP/v.script" --frame furnace --spp 1024 \
  --max-bounces 0 -o "$TMP/ref-direct.exr"
for part in all direct; do
  r=$TMP/ref.exr
  [ $part = direct ] && r=$TMP/ref-direct.exr
  gi-compare diff "$TMP/$part/furnace.exr" "$r" >"$TMP/d" 2>&1
  e=$(awk -F= '$1 == "nrmse" { print $2 }' "$TMP/d")
  ma=$(awk -F= '$1 == "mean_a" { print $2 }' "$TMP/d") mr=$(awk -F= '$1 == "mean_ref" { print $2 }' "$TMP/d")
  check "$part: within nrmse 0.05 of the path tracer (nrmse $e; mean $ma against $mr cd/m^2)" \
    awk -v a="$e" 'BEGIN { exit !(a != "" && a + 0 < 0.05) }'
done
finish
