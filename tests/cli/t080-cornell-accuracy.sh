#!/usr/bin/env bash
# t080-cornell-accuracy: every frame of the Cornell-box variants, relit at
# reduced size (64x64) with the default options (one sample per pixel, edge,
# shadow-edge and penumbra refinement, footprint-filtered textures) and with
# 6x6 samples per pixel, is within nrmse 0.05 of a path-traced reference of
# 4096 samples per pixel (whose own noise is about 0.015 nrmse: two seeds
# differ by 0.02). The issue's accuracy figure, held in CI. Skipped under the
# sanitizers, where the references would take too long; the same code runs
# there through the other tests.
. "$(dirname "$0")/lib.sh"
skip_under_sanitizers
S=$TMP/cornell.gltf
"$BUILD/tools/mkcornell" "$S" 2>/dev/null
sed 's/^resolution .*/resolution 64 64/' "$GI_ROOT/examples/cornell-box/variants.script" >"$TMP/v.script"
expect_success "precompute" gi-precompute -q "$S" -o "$TMP/c.gip"
expect_success "hvds" gi-hvds -q "$S" "$TMP/c.gip" -o "$TMP/c.gih"
expect_success "relight all frames, defaults" gi-relight -q "$S" "$TMP/c.gip" "$TMP/c.gih" "$TMP/v.script" -o "$TMP/def"
expect_success "relight all frames, --ss 6" gi-relight -q "$S" "$TMP/c.gip" "$TMP/c.gih" "$TMP/v.script" -o "$TMP/out" --ss 6
frames=$(awk '$1 == "frame" { print $2 }' "$TMP/v.script")
for f in $frames; do
  gi-compare render -q "$S" "$TMP/v.script" --frame "$f" --spp 4096 -o "$TMP/ref-$f.exr" ||
    { not_ok "reference of $f"; continue; }
  for run in def out; do
    gi-compare diff "$TMP/$run/$f.exr" "$TMP/ref-$f.exr" --tolerance 0.05 >"$TMP/d.txt" 2>&1; rc=$?
    e=$(awk -F= '$1 == "nrmse" { print $2 }' "$TMP/d.txt")
    what=$([ $run = def ] && echo defaults || echo "--ss 6")
    if [ $rc -eq 0 ]; then ok "frame $f ($what): nrmse $e <= 0.05"
    else not_ok "frame $f ($what): nrmse $e > 0.05 (exit $rc)"; fi
  done
done
finish
