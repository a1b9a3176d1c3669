#!/usr/bin/env bash
# t145-relight-fresh-view: --fresh-paths starts its paths preferably where the last
# frame's gathering points look (--fresh-view, on by default). The office of t144 under a
# sun, 64 x 48: the sun's light falls mostly on the roof and the outer walls, whose paths
# leave the scene, and comes in only at the window. Measured 2026-12-08 at 320 x 240: 1.2%
# of the lit entry points' flux is on surfaces the view's points see; auto reached an
# effective sample size of 128,779 with 1.69 M paths where, in proportion to flux alone,
# 4.19 M paths (its cap) reached 35,952. The frames are the same light on average: with
# and without, they stay as near each other and the path tracer as two runs of either.
. "$(dirname "$0")/lib.sh"
command -v python3 >/dev/null || { echo "ok 1 # skip python3 missing"; exit 0; }
S=$TMP/office.gltf
python3 "$(dirname "$0")/mkoffice.py" "$S" || { not_ok "writing the office"; finish; }
cat >"$TMP/o.script" <<'SCRIPT'
resolution 64 48
camera position 5.2 1.6 4.6 target 2.5 0.9 1.5 up 0 1 0 fov 65
light sun directional direction -0.3 -0.6 0.75 illuminance 60000 color 1 0.95 0.88
frame sun
light sun directional direction 0.25 -0.5 0.83 illuminance 60000 color 1 0.95 0.88
frame sun-moved
SCRIPT
expect_success "precompute" gi-precompute -q "$S" -o "$TMP/o.gip" --photons 200000
expect_success "hvds" gi-hvds -q "$S" "$TMP/o.gip" -o "$TMP/o.gih"
R() { gi-relight "$S" "$TMP/o.gip" "$TMP/o.gih" "$TMP/o.script" "$@"; }
expect_success "relight, --fresh-paths 200000, -v" R -v -o "$TMP/on" --fresh-paths 200000 -j 2
cp "$TMP/stderr" "$TMP/on.err"
expect_stderr "fresh paths: [0-9]+ of the lit entry points \(([0-9.]+)% of their flux\) on surfaces the last view" \
  "-v reports the entry points the view's points see"
share=$(sed -nE 's/.*lit entry points \(([0-9.]+)% of their flux\).*/\1/p' "$TMP/on.err" | head -1)
check "the first frame has no view to weigh by: one such line, for the second light ($(grep -c 'of the lit entry points' "$TMP/on.err"))" \
  test "$(grep -c 'of the lit entry points' "$TMP/on.err")" = 1
check "under the sun the view's surfaces hold under 10% of the lit flux ($share%)" \
  awk -v a="$share" 'BEGIN { exit !(a != "" && a + 0 < 10) }'
expect_success "relight, --fresh-view off" R -v -o "$TMP/off" --fresh-paths 200000 --fresh-view off -j 2
cp "$TMP/stderr" "$TMP/off.err"
check "--fresh-view off weighs by flux alone (no such line)" test "$(grep -c 'of the lit entry points' "$TMP/off.err")" = 0
# the second light state's effective sample size of the fresh paths, as many paths either way
ess() { grep -E "effective sample sizes" "$1" | tail -1 | sed -E 's/.*and ([0-9]+) \(fresh\).*/\1/'; }
e_on=$(ess "$TMP/on.err") e_off=$(ess "$TMP/off.err")
check "200000 paths reach a larger effective sample size from the view's surfaces ($e_on against $e_off)" \
  awk -v a="$e_on" -v b="$e_off" 'BEGIN { exit !(a != "" && b != "" && a + 0 > 2 * b) }'
expect_success "relight, one thread" R -q -o "$TMP/on1" --fresh-paths 200000 -j 1
e=$(gi-compare diff "$TMP/on1/sun-moved.exr" "$TMP/on/sun-moved.exr" | awk -F= '$1 == "nrmse" { print $2 }')
check "one thread gives what two give (nrmse $e)" awk -v a="$e" 'BEGIN { exit !(a != "" && a + 0 == 0) }'
expect_exit 2 "a bad --fresh-view is a usage error" R -q -o "$TMP/bad" --fresh-view maybe
expect_stderr "fresh-view: expected on or off" "and says what it expected"
if [ "${GI_SANITIZE:-0}" != 1 ]; then
  expect_success "reference, 1024 spp" gi-compare render -q "$S" "$TMP/o.script" --frame sun-moved --spp 1024 \
    -o "$TMP/ref.exr"
  a=$(gi-compare diff "$TMP/on/sun-moved.exr" "$TMP/ref.exr" | awk -F= '$1 == "nrmse_excess" { print $2 }')
  b=$(gi-compare diff "$TMP/off/sun-moved.exr" "$TMP/ref.exr" | awk -F= '$1 == "nrmse_excess" { print $2 }')
  check "both unbiased: within 0.01 of each other against the path tracer ($a, $b net of its noise)" \
    awk -v a="$a" -v b="$b" 'BEGIN { d = a - b; if (d < 0) d = -d; exit !(a != "" && b != "" && d < 0.01) }'
fi
finish
