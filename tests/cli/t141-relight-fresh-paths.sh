#!/usr/bin/env bash
# t141-relight-fresh-paths: gi-relight --fresh-paths on the Cornell box (48 x 48, a spot on
# a wall, then a lamp 5 cm from the left wall). Off (0) gives the frames of the default; on,
# -v reports the paths and both estimates' effective sample sizes, the fresh ones larger
# beside the lamp (the .gip's flux there spans orders of magnitude); one thread gives the
# frames two give; the frames move, but stay near those without (the same light, two
# unbiased estimates of its later bounces); auto traces a pilot and then as many paths as
# reach its target, the same for any thread count; a bad count is a usage error.
. "$(dirname "$0")/lib.sh"
S=$TMP/cornell.gltf
"$BUILD/tools/mkcornell" "$S" 2>/dev/null
cat >"$TMP/v.script" <<'SCRIPT'
resolution 48 48
camera position 0.278 0.273 -0.8 target 0.278 0.273 0 up 0 1 0 fov 39.3076
light ceiling off
light s1 spot position 0.1 0.45 0.1 direction 0.35 -0.25 0.45 intensity 3 outer 20 inner 15
frame spot-wall
light s1 off
light lamp point position 0.505 0.3 0.28 intensity 0.5
frame lamp-by-wall
SCRIPT
expect_success "precompute" gi-precompute -q "$S" -o "$TMP/c.gip" --photons 200000
expect_success "hvds" gi-hvds -q "$S" "$TMP/c.gip" -o "$TMP/c.gih"
R() { gi-relight "$S" "$TMP/c.gip" "$TMP/c.gih" "$TMP/v.script" "$@"; }
expect_success "relight, defaults" R -q -o "$TMP/def"
expect_success "relight, --fresh-paths 0" R -q -o "$TMP/off" --fresh-paths 0
expect_success "relight, --fresh-paths 20000, 2 threads, -v" R -v -o "$TMP/on2" --fresh-paths 20000 -j 2
expect_stderr "fresh paths: 20000 from [0-9]+ lit diffuse entry points, [0-9]+ photons summed into keys" \
  "-v reports the fresh paths"
ess=$(grep -E "effective sample sizes" "$TMP/stderr" | tail -1 |
  sed -E 's/.*sample sizes ([0-9]+) \(.gip\) and ([0-9]+) \(fresh\).*/\1 \2/')
check "beside the lamp the fresh paths' effective sample size is the larger ($ess)" \
  awk -v s="$ess" 'BEGIN { split(s, a, " "); exit !(a[1] > 0 && a[2] > a[1]) }'
expect_success "relight, --fresh-paths 20000, 1 thread" R -q -o "$TMP/on1" --fresh-paths 20000 -j 1
for f in spot-wall lamp-by-wall; do
  e=$(gi-compare diff "$TMP/off/$f.exr" "$TMP/def/$f.exr" | awk -F= '$1 == "nrmse" { print $2 }')
  check "$f: --fresh-paths 0 is the default (nrmse $e)" awk -v a="$e" 'BEGIN { exit !(a != "" && a + 0 == 0) }'
  e=$(gi-compare diff "$TMP/on1/$f.exr" "$TMP/on2/$f.exr" | awk -F= '$1 == "nrmse" { print $2 }')
  check "$f: one thread gives what two give (nrmse $e)" awk -v a="$e" 'BEGIN { exit !(a != "" && a + 0 == 0) }'
  e=$(gi-compare diff "$TMP/on2/$f.exr" "$TMP/def/$f.exr" | awk -F= '$1 == "nrmse" { print $2 }')
  check "$f: fresh paths move the frame, within nrmse 0.05 of it ($e)" \
    awk -v a="$e" 'BEGIN { exit !(a != "" && a + 0 > 0 && a + 0 < 0.05) }'
done
# auto: a pilot of 16384 paths, then as many as its yield says reach an effective sample
# size of 131072 with the .gip's (this small .gip's later photons fall far short of it)
expect_success "relight, --fresh-paths auto, 2 threads, -v" R -v -o "$TMP/auto2" --fresh-paths auto -j 2
n_auto=$(grep -E "^gi-relight: fresh paths: [0-9]+ from" "$TMP/stderr" | sed -E 's/.*fresh paths: ([0-9]+) from.*/\1/' | tr '\n' ' ')
check "auto traces more than the pilot under both lights ($n_auto)" \
  awk -v s="$n_auto" 'BEGIN { n = split(s, a, " "); exit !(n == 2 && a[1] > 16384 && a[2] > 16384 && a[1] <= 4194304) }'
ess=$(grep -E "effective sample sizes" "$TMP/stderr" | sed -E 's/.*sample sizes ([0-9]+) \(.gip\) and ([0-9]+) \(fresh\).*/\1 \2/' | tr '\n' ' ')
check "and reaches about 131072 together with the .gip's ($ess)" \
  awk -v s="$ess" 'BEGIN { split(s, a, " "); for (i = 1; i <= 4; i += 2) { t = a[i] + a[i + 1]; if (!(t > 0.8 * 131072 && t < 1.3 * 131072)) exit 1 } }'
expect_success "relight, --fresh-paths auto, 1 thread" R -q -o "$TMP/auto1" --fresh-paths auto -j 1
for f in spot-wall lamp-by-wall; do
  e=$(gi-compare diff "$TMP/auto1/$f.exr" "$TMP/auto2/$f.exr" | awk -F= '$1 == "nrmse" { print $2 }')
  check "$f, auto: one thread gives what two give (nrmse $e)" awk -v a="$e" 'BEGIN { exit !(a != "" && a + 0 == 0) }'
  e=$(gi-compare diff "$TMP/auto2/$f.exr" "$TMP/def/$f.exr" | awk -F= '$1 == "nrmse" { print $2 }')
  check "$f, auto: within nrmse 0.05 of the default ($e)" \
    awk -v a="$e" 'BEGIN { exit !(a != "" && a + 0 > 0 && a + 0 < 0.05) }'
done
# every light off: nothing to trace, and -v says so
printf 'resolution 16 16\ncamera position 0.278 0.273 -0.8 target 0.278 0.273 0 up 0 1 0 fov 39.3076\nlight ceiling off\nframe dark\n' >"$TMP/dark.script"
expect_success "relight, every light off, --fresh-paths auto -v" \
  gi-relight "$S" "$TMP/c.gip" "$TMP/c.gih" "$TMP/dark.script" -v -o "$TMP/dark" --fresh-paths auto
expect_stderr "fresh paths: 0 from 0 lit diffuse entry points, 0 photons" "-v reports no path where nothing is lit"
check "and no negative time" sh -c "! grep -E 'fresh paths: traced by -' '$TMP/stderr'"
expect_exit 2 "--fresh-paths autox is a usage error" R -q -o "$TMP/bad" --fresh-paths autox
expect_exit 2 "--fresh-paths -1 is a usage error" R -q -o "$TMP/bad" --fresh-paths -1
expect_stderr "fresh-paths" "the message names the option"
expect_exit 2 "--fresh-paths abc is a usage error" R -q -o "$TMP/bad" --fresh-paths abc
finish
