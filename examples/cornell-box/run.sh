#!/usr/bin/env bash
# examples/cornell-box/run.sh - the demo (`make demo`): the whole pipeline on
# the measured Cornell box. Builds the scene, precomputes photon paths and the
# HVDS, relights every frame of variants.script, renders path-traced
# references of some frames and prints a table of frame times and errors.
# Environment: BIN (tools), BUILD (build dir), OUT (output dir, default
# out/cornell-box), DEMO_SPP (reference samples per pixel, default 512),
# DEMO_REF_FRAMES (frames that get a reference, default "published panel blue-left-wall camera-moved").
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
BIN=$(cd "${BIN:-$root/bin}" && pwd)
BUILD=$(cd "${BUILD:-$root/build}" && pwd)
OUT=${OUT:-$root/out/cornell-box}
SPP=${DEMO_SPP:-512}
REF_FRAMES=${DEMO_REF_FRAMES:-"published panel blue-left-wall camera-moved"}
mkdir -p "$OUT"
export MESA_SHADER_CACHE_DISABLE=true
scene=$OUT/cornell-box.gltf script=$here/variants.script

echo "== 1. scene: $scene"
"$BUILD/tools/mkcornell" "$scene" 2>/dev/null
echo "== 2. gi-precompute"
"$BIN/gi-precompute" "$scene" -o "$OUT/cornell-box.gip"
echo "== 3. gi-hvds"
"$BIN/gi-hvds" "$scene" "$OUT/cornell-box.gip" -o "$OUT/cornell-box.gih"
echo "== 4. gi-relight: every frame of variants.script"
"$BIN/gi-relight" -q "$scene" "$OUT/cornell-box.gip" "$OUT/cornell-box.gih" "$script" -o "$OUT/relight" \
    --png --exposure -1 --timings "$OUT/timings.csv"
echo "== 5. references (gi-compare render, $SPP spp) and errors (gi-compare diff)"
declare -A nrmse refsec refnoise excess
for f in $REF_FRAMES; do
  "$BIN/gi-compare" render "$scene" "$script" --frame "$f" --spp "$SPP" -q -o "$OUT/ref-$f.exr"
  refsec[$f]=$(oiiotool --info -v "$OUT/ref-$f.exr" 2>/dev/null | awk -F'"' '/gi:seconds/ {print $2}')
  "$BIN/gi-compare" diff "$OUT/relight/$f.exr" "$OUT/ref-$f.exr" --error-image "$OUT/error-$f.png" \
      > "$OUT/diff-$f.txt"
  nrmse[$f]=$(awk -F= '$1 == "nrmse" {printf "%.4f", $2}' "$OUT/diff-$f.txt")
  refnoise[$f]=$(awk -F= '$1 == "ref_noise_nrmse" {printf "%.4f", $2}' "$OUT/diff-$f.txt")
  excess[$f]=$(awk -F= '$1 == "nrmse_excess" {printf "%.4f", $2}' "$OUT/diff-$f.txt")
done
echo
printf '%-20s %-26s %10s %10s %10s %10s %12s\n' frame changed relight_ms nrmse ref_noise beyond reference_s
tail -n +2 "$OUT/timings.csv" | while IFS=, read -r idx name changed w h tdi tpe thv tfg tsp tmat tgb ttot; do
  printf '%-20s %-26s %10.1f %10s %10s %10s %12s\n' "$name" "$changed" "$ttot" "${nrmse[$name]:--}" \
    "${refnoise[$name]:--}" "${excess[$name]:--}" "${refsec[$name]:--}"
done
echo
echo "made in $OUT: cornell-box.gltf/.gip/.gih, relight/<frame>.exr + .png (linear cd/m^2 and sRGB),"
echo "timings.csv, ref-<frame>.exr (path traced, $SPP spp), error-<frame>.png (relative error maps) and"
echo "diff-<frame>.txt (gi-compare diff of the relit frame against its reference)"
echo "(nrmse includes the reference's own Monte Carlo noise at $SPP spp, which the reference estimates"
echo " from its two halves: ref_noise; beyond = sqrt(nrmse^2 - ref_noise^2), the relight's error net of it)"
