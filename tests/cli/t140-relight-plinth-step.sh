#!/usr/bin/env bash
# t140-relight-plinth-step: a plate 5 cm above a floor (mkplate.py) under a sun, its top seen
# from straight above at 64 x 48, with gathering points as far apart for the step as Sponza's
# (gi-hvds --r-min 0.05 --r-max 0.25; there R- is 4.6 cm and a plinth overhangs the rail
# 5 cm below it). The floor's points under the plate read no light, and they lay within the
# irradiance-cache reach of the samples on the plate's top: same normal, a distance of about
# one radius. The top's indirect light read 0.191 nrmse against 512 spp, its mean 0.83 of
# the path tracer's. A point off the sample's tangent plane by more than 0.4 of its radius is
# now out of reach (gi_shade.c, GI_SHADE_PLANE): 0.050 (the reference's own noise 0.042),
# the mean 0.996.
. "$(dirname "$0")/lib.sh"
command -v python3 >/dev/null || { echo "ok 1 # skip python3 missing"; exit 0; }
S=$TMP/plate.gltf
python3 "$(dirname "$0")/mkplate.py" "$S" 0.05 || { not_ok "writing the plate"; finish; }
cat >"$TMP/v.script" <<'SCRIPT'
resolution 64 48
camera position 0.8 1.0 0 target 0.8 0 0 up -1 0 0 fov 40
light sun directional direction -0.6 -1 0.1 illuminance 1000
frame top
SCRIPT
expect_success "precompute" gi-precompute -q "$S" -o "$TMP/d.gip" --photons 100000
expect_success "hvds" gi-hvds -q "$S" "$TMP/d.gip" -o "$TMP/d.gih" --r-min 0.05 --r-max 0.25
expect_success "relight, indirect light" gi-relight -q "$S" "$TMP/d.gip" "$TMP/d.gih" "$TMP/v.script" -o "$TMP/out" \
  --only indirect
expect_success "reference, indirect light, 512 spp" gi-compare render -q "$S" "$TMP/v.script" --spp 512 \
  --min-bounces 1 -o "$TMP/ref.exr"
gi-compare diff "$TMP/out/top.exr" "$TMP/ref.exr" >"$TMP/diff.txt"
e=$(awk -F= '$1 == "nrmse" { print $2 }' "$TMP/diff.txt")
r=$(awk -F= '$1 == "mean_a" { a = $2 } $1 == "mean_ref" { b = $2 } END { if (b > 0) print a / b }' "$TMP/diff.txt")
check "the plate's top within nrmse 0.08 of the reference ($e)" awk -v a="$e" 'BEGIN { exit !(a != "" && a + 0 < 0.08) }'
check "its mean within 5% of the reference's ($r)" awk -v a="$r" 'BEGIN { exit !(a != "" && a > 0.95 && a < 1.05) }'
finish
