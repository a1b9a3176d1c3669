#!/usr/bin/env bash
# t143-relight-glossy-window: a metal's reflection is not a mosaic. Only the
# pixels of a grid gather glossy rays (every 2nd pixel, every 4th for a wide
# lobe), and every pixel averages the gathers within a window around it. With
# a box window the gathers came in and went out all at once, every grid
# spacing: the pixels between two steps took the very same gathers, and the
# reflection was made of flat 2 x 2 or 4 x 4 blocks (seen on a steel cabinet in
# an office under a sun). The window's edges now ramp over one grid spacing.
# The room of t110 at 160 x 120, metal floor at roughness 0.5 (the 4-pixel
# grid) and 0.3 (the 2-pixel grid), indirect light only (the metal has no
# diffuse part): in a block of floor pixels, in every phase of x mod 4 and of
# y mod 4, at most 5% of neighbouring pixels are equal (to 1e-4). Measured
# 2026-12-08 with the box: 252 / 288 in x (87%) at 0.5, 46 / 288 in y (16%)
# at 0.3; with the ramp at most 3 / 288.
. "$(dirname "$0")/lib.sh"
command -v python3 >/dev/null || { echo "ok 1 # skip python3 missing"; exit 0; }
command -v oiiotool >/dev/null || { echo "ok 1 # skip oiiotool missing (make deps)"; exit 0; }
S=$TMP/room.gltf
python3 "$(dirname "$0")/mkroom.py" "$S" --metal-floor 0.5 || { not_ok "writing the room"; finish; }
cat >"$TMP/v.script" <<'SCRIPT'
resolution 160 120
camera position 2.7 1.6 0.3 target 1.2 0.2 2.0 up 0 1 0 fov 60
frame rough05
material metal roughness 0.3
frame rough03
SCRIPT
expect_success "precompute" gi-precompute -q "$S" -o "$TMP/r.gip" --photons 200000
expect_success "hvds" gi-hvds -q "$S" "$TMP/r.gip" -o "$TMP/r.gih"
expect_success "relight, indirect light" gi-relight -q "$S" "$TMP/r.gip" "$TMP/r.gih" "$TMP/v.script" -o "$TMP/out" \
  --only indirect
# the largest share, over the phases of x mod 4 and y mod 4, of neighbouring
# pixels (luminance) within 1e-4 of each other, in the 48 x 24 pixels of
# floor at the bottom left
flat_share() {
  oiiotool "$1" --cut 48x24+0+96 -o "$TMP/block.exr" 2>/dev/null || return
  oiiotool --dumpdata "$TMP/block.exr" | awk '
    /Pixel/ { gsub(/[(),:]/, " "); L[$2, $3] = 0.2126 * $4 + 0.7152 * $5 + 0.0722 * $6; n++ }
    function flat(a, b,   d) { d = a - b; if (d < 0) d = -d; return d <= 1e-4 * (a > b ? a : b) }
    END {
      if (n != 48 * 24) exit 1
      for (y = 0; y < 24; y++) for (x = 0; x < 47; x++) { zx[x % 4] += flat(L[x + 1, y], L[x, y]); nx[x % 4]++ }
      for (x = 0; x < 48; x++) for (y = 0; y < 23; y++) { zy[y % 4] += flat(L[x, y + 1], L[x, y]); ny[y % 4]++ }
      m = 0
      for (k = 0; k < 4; k++) { if (zx[k] / nx[k] > m) m = zx[k] / nx[k]; if (zy[k] / ny[k] > m) m = zy[k] / ny[k] }
      printf "%.4f\n", m
    }'
}
for f in rough05 rough03; do
  s=$(flat_share "$TMP/out/$f.exr")
  check "'$f': at most 5% of neighbouring floor pixels equal in any grid phase ($s)" \
    awk -v a="$s" 'BEGIN { exit !(a != "" && a + 0 <= 0.05) }'
done
# the ramp keeps the window's reach: against every pixel gathering
# (--glossy-stride 1), as near as the box was (t110: 0.104 against the
# reference at 64 x 48)
expect_success "relight, every pixel gathering" gi-relight -q "$S" "$TMP/r.gip" "$TMP/r.gih" "$TMP/v.script" \
  -o "$TMP/s1" --only indirect --glossy-stride 1 --frames rough05
d=$(gi-compare diff "$TMP/out/rough05.exr" "$TMP/s1/rough05.exr" 2>/dev/null | awk -F= '$1 == "nrmse" { print $2 }')
check "'rough05' within 0.1 of every pixel gathering (nrmse $d)" awk -v a="$d" 'BEGIN { exit !(a != "" && a + 0 < 0.1) }'
finish
