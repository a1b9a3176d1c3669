#!/usr/bin/env bash
# t087-relight-only: gi-relight --only direct|indirect renders one part of the
# light, split as the path tracer splits it (gi-compare render --max-bounces 0
# and --min-bounces 1): light that reaches the camera with no bounce but off
# the light's own surface (an area light seen directly, emission) is direct.
# The two parts add up to the full frame exactly, and each matches its
# reference. Measured 2026-12-01 on the Cornell box at 48 x 48 against 1024
# spp: direct nrmse 0.051 (point light) and 0.015 (panel), indirect 0.073 and
# 0.071, means within 0.3%; before the split was exact, the panel seen by the
# camera was in both parts (indirect nrmse 25).
. "$(dirname "$0")/lib.sh"
command -v oiiotool >/dev/null || { echo "ok 1 # skip oiiotool missing (make deps)"; exit 0; }
S=$TMP/cornell.gltf
"$BUILD/tools/mkcornell" -q "$S" || { not_ok "mkcornell makes the scene"; finish; }
sed 's/^resolution .*/resolution 48 48/' "$GI_ROOT/examples/cornell-box/variants.script" >"$TMP/v.script"
expect_success "precompute" gi-precompute -q "$S" -o "$TMP/c.gip"
expect_success "hvds" gi-hvds -q "$S" "$TMP/c.gip" -o "$TMP/c.gih"
for part in all direct indirect; do
  opt=()
  [ $part != all ] && opt=(--only $part)
  expect_success "relight, $part" gi-relight -q "$S" "$TMP/c.gip" "$TMP/c.gih" "$TMP/v.script" -o "$TMP/$part" \
    --frames 0-2 "${opt[@]}"
done
expect_exit 2 "--only with another value is a usage error" \
  gi-relight -q "$S" "$TMP/c.gip" "$TMP/c.gih" "$TMP/v.script" -o "$TMP/bad" --only glossy
expect_stderr "--only: expected direct or indirect" "the message names the option and the choices"

val() { awk -F= -v k="$1" '$1 == k { print $2 }' "$2"; }
if [ "${GI_SANITIZE:-0}" = 1 ]; then spp=16; else spp=1024; fi
for f in published panel; do
  oiiotool "$TMP/direct/$f.exr" "$TMP/indirect/$f.exr" --add -o "$TMP/sum-$f.exr" 2>/dev/null
  gi-compare diff "$TMP/sum-$f.exr" "$TMP/all/$f.exr" >"$TMP/d.txt" 2>&1
  check "$f: direct + indirect is the full frame (rms $(val rms "$TMP/d.txt"))" \
    awk -v a="$(val rms "$TMP/d.txt")" 'BEGIN { exit !(a != "" && a + 0 < 1e-5) }'
  check "$f: the parts differ from the frame and from each other" \
    sh -c "! cmp -s '$TMP/direct/$f.exr' '$TMP/all/$f.exr' && ! cmp -s '$TMP/indirect/$f.exr' '$TMP/direct/$f.exr'"
  expect_success "$f: direct reference, $spp spp" \
    gi-compare render -q "$S" "$TMP/v.script" --frame $f --spp $spp --max-bounces 0 -o "$TMP/rd-$f.exr"
  expect_success "$f: indirect reference, $spp spp" \
    gi-compare render -q "$S" "$TMP/v.script" --frame $f --spp $spp --min-bounces 1 -o "$TMP/ri-$f.exr"
  [ "${GI_SANITIZE:-0}" = 1 ] && continue # the figures need the plain build's references
  for part in direct indirect; do
    ref=$TMP/rd-$f.exr
    [ $part = indirect ] && ref=$TMP/ri-$f.exr
    gi-compare diff "$TMP/$part/$f.exr" "$ref" >"$TMP/d.txt" 2>&1
    e=$(val nrmse "$TMP/d.txt") ma=$(val mean_a "$TMP/d.txt") mr=$(val mean_ref "$TMP/d.txt")
    check "$f: $part part within nrmse 0.1 of its reference ($e)" \
      awk -v a="$e" 'BEGIN { exit !(a != "" && a + 0 < 0.1) }'
    check "$f: $part mean within 2% of the reference's ($ma against $mr)" \
      awk -v a="$ma" -v r="$mr" 'BEGIN { d = a / r - 1; if (d < 0) d = -d; exit !(r > 0 && d < 0.02) }'
  done
done
finish
