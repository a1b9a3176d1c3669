#!/usr/bin/env bash
# examples/cornell-box/run.sh - the demo (`make demo`): builds the measured
# Cornell box, then runs what exists of the pipeline on it and says what it made.
# Environment: BIN (tools), BUILD (build dir), OUT (output dir, default out/cornell-box),
# DEMO_SPP (reference samples per pixel, default 256).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
BIN=$(cd "${BIN:-$root/bin}" && pwd)
BUILD=$(cd "${BUILD:-$root/build}" && pwd)
OUT=${OUT:-$root/out/cornell-box}
SPP=${DEMO_SPP:-256}
mkdir -p "$OUT"
export MESA_SHADER_CACHE_DISABLE=true

echo "== scene: $OUT/cornell-box.gltf"
"$BUILD/tools/mkcornell" "$OUT/cornell-box.gltf"
"$BIN/gi-compare" info "$OUT/cornell-box.gltf" > "$OUT/scene.json"
echo "   $(grep -o '"triangles": *[0-9]*' "$OUT/scene.json" | head -1), info in $OUT/scene.json"

frames=$(grep -E '^[[:space:]]*frame[[:space:]]' "$here/variants.script" | awk '{print $2}')
echo "== references (gi-compare render, $SPP spp) of the frames of variants.script"
printf '%-22s %10s %10s\n' frame seconds mean_nits
for f in $frames; do
  "$BIN/gi-compare" render "$OUT/cornell-box.gltf" "$here/variants.script" --frame "$f" \
      --spp "$SPP" --size 320x320 -q -o "$OUT/ref-$f.exr"
  secs=$(oiiotool --info -v "$OUT/ref-$f.exr" 2>/dev/null | awk -F'"' '/gi:seconds/ {print $2}')
  mean=$(oiiotool --stats "$OUT/ref-$f.exr" 2>/dev/null | awk '/Avg:/ {printf "%.4g", ($2+$3+$4)/3; exit}')
  printf '%-22s %10s %10s\n' "$f" "${secs:-?}" "${mean:-?}"
done
echo "== made: $OUT/cornell-box.gltf and ref-<frame>.exr for each frame (linear cd/m^2)"
echo "   (precompute, hvds and relight are not implemented yet: see the open issues)"
