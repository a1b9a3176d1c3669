#!/usr/bin/env bash
# t085-gpoints: gi-relight --gpoints writes each frame's gathering points as a
# gi-compare sensors points file, and their indirect illuminance matches the
# path tracer's (gi-compare sensors --min-bounces 1) on the Cornell box: the
# object-space half of the relight (entry points, photon energies, HVDS,
# final gather) checked on its own, before interpolation and splatting.
# Measured (2026-12-01, 582 points, 4096 spp): ratio of sums 0.993-0.994, rms
# error 0.045-0.049 of the mean, of which the sensors' own noise is about 0.025.
. "$(dirname "$0")/lib.sh"
S=$TMP/cornell.gltf
"$BUILD/tools/mkcornell" -q "$S" || { not_ok "mkcornell makes the scene"; finish; }
sed 's/^resolution .*/resolution 32 32/' "$GI_ROOT/examples/cornell-box/variants.script" >"$TMP/v.script"
expect_success "precompute" gi-precompute -q "$S" -o "$TMP/c.gip"
expect_success "hvds" gi-hvds -q "$S" "$TMP/c.gip" -o "$TMP/c.gih"
expect_success "relight three frames with --gpoints" \
  gi-relight -q "$S" "$TMP/c.gip" "$TMP/c.gih" "$TMP/v.script" -o "$TMP/out" --frames 0-2 --gpoints
for f in published point-lowered panel; do
  check "$f.gpoints is written beside $f.exr" test -s "$TMP/out/$f.gpoints" -a -s "$TMP/out/$f.exr"
done
G=$TMP/out/published.gpoints
n=$(sed -n '1s/.*: \([0-9]*\) points$/\1/p' "$G")
check "the header gives the number of points ($n) and one line follows per point" \
  [ -n "$n" ] && [ "$n" -gt 100 ] && [ "$(grep -vc '^#' "$G")" -eq "$n" ]
check "every point line: 6 numbers, '#', irradiance (lux, RGB), radius, index in order, lifted part of E, later bounces (at least the lifted part, at most E)" \
  awk '!/^#/ { if (NF != 15 || $7 != "#" || $8 < 0 || $12 <= 0 || $13 != i || $14 < 0 || $14 > $8 * 1.001 + 1e-6 || $15 < $14 * 0.999 - 1e-6 || $15 > $8 * 1.001 + 1e-6) bad = 1; i++ } END { exit bad }' "$G"
check "no temporary file is left" [ -z "$(ls "$TMP/out" | grep -F .tmp.)" ]
differ() { ! cmp -s "$1" "$2"; }
check "the points' irradiance follows the light's move" differ "$G" "$TMP/out/point-lowered.gpoints"

# every 40th point goes to the path tracer, which reads the file as it is
if [ "${GI_SANITIZE:-0}" = 1 ]; then spp=16; else spp=4096; fi
for f in published panel; do
  awk '!/^#/ && (NR % 40 == 0)' "$TMP/out/$f.gpoints" >"$TMP/p-$f.txt"
  expect_success "sensors read the points of $f (indirect light only, $spp spp)" \
    gi-compare sensors -q "$S" "$TMP/v.script" --frame "$f" --points "$TMP/p-$f.txt" --spp $spp --min-bounces 1
  cp "$TMP/stdout" "$TMP/s-$f.txt"
  check "$f: one estimate per point" [ "$(wc -l <"$TMP/s-$f.txt")" -eq "$(wc -l <"$TMP/p-$f.txt")" ]
  [ "${GI_SANITIZE:-0}" = 1 ] && continue # the accuracy needs the plain build's speed
  stats=$(paste -d' ' "$TMP/p-$f.txt" "$TMP/s-$f.txt" | awk '{ e += $8; t += $(NF - 1); d += ($8 - $(NF - 1))^2; n++ }
    END { printf "%.4f %.4f", e / t, sqrt(d / n) / (t / n) }')
  ratio=${stats% *} rms=${stats#* }
  check "$f: gathering points hold the path tracer's indirect light in sum (ratio $ratio in 0.96..1.04)" \
    awk -v r="$ratio" 'BEGIN { exit !(r >= 0.96 && r <= 1.04) }'
  check "$f: and point by point (rms error $rms of the mean <= 0.08, sensor noise included)" \
    awk -v r="$rms" 'BEGIN { exit !(r <= 0.08) }'
  # the later bounces alone (column 15) against paths that bounced twice or more
  expect_success "sensors read the light of two bounces or more at the points of $f" \
    gi-compare sensors -q "$S" "$TMP/v.script" --frame "$f" --points "$TMP/p-$f.txt" --spp $spp --min-bounces 2
  later=$(paste -d' ' "$TMP/p-$f.txt" "$TMP/stdout" | awk '{ e += $15; t += $(NF - 1) } END { printf "%.4f", e / t }')
  check "$f: the points' later bounces are the path tracer's in sum (ratio $later in 0.93..1.07)" \
    awk -v r="$later" 'BEGIN { exit !(r >= 0.93 && r <= 1.07) }'
done
finish
