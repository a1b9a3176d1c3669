#!/usr/bin/env bash
# t021-compare-sensors.sh - gi-compare sensors on the Cornell box: one
# "lux stderr" line per point, the inverse-square law for direct light under
# the point light, full shadow behind a wall, direct + indirect (--max-bounces 0,
# --min-bounces 1) = the full value, -j independence, and the
# exit codes and file:line:column messages for bad points files.
source "$(dirname "$0")/lib.sh"
GC=$BIN/gi-compare
MC=${BUILD:-$GI_ROOT/build}/tools/mkcornell
if [ ! -x "$GC" ] || [ ! -x "$MC" ]; then
  echo "ok 1 # skip gi-compare or build/tools/mkcornell not built"
  exit 0
fi
"$MC" -q "$TMP/cornell.gltf" || { not_ok "mkcornell makes the scene"; finish; }
SC=$TMP/cornell.gltf

# The Cornell light "ceiling" is a 2 cd white point light at (0.278, 0.45, 0.2795).
# Comments, blank lines, CRLF and tabs are allowed in a points file.
printf '%s\n' '# x y z nx ny nz (metres)' \
  '0.278 0.001 0.2795   0 1 0     # floor, 0.449 m straight below the light' \
  '' '   ' \
  '	0.278 0.27 1.0	0 0 -2      # outside, behind the back wall, facing it (normal not unit)' >"$TMP/pts.txt"
printf '0.1 0.3 0.3 1 0 0\r\n# last line without a newline' >>"$TMP/pts.txt"

# line N COL: field COL of stdout line N.
line() { sed -n "$1p" "$TMP/stdout" | awk -v c="$2" '{ print $c }'; }
differ() { ! cmp -s "$1" "$2"; }

# ---- direct light only: exact inverse-square law -----------------------------
expect_success "sensors, direct light only (--max-bounces 0)" \
  "$GC" sensors "$SC" --points "$TMP/pts.txt" --spp 64 --max-bounces 0
check "one line per point (3)" [ "$(wc -l <"$TMP/stdout")" -eq 3 ]
check "every line is two numbers" awk 'NF != 2 || $1 + 0 != $1 || $2 + 0 != $2 { bad = 1 } END { exit bad }' "$TMP/stdout"
e=$(line 1 1) s=$(line 1 2)
check "floor under the light: E = I/d^2 = 2/0.449^2 lx within 3 stderr (E=$e +- $s)" \
  awk -v e="$e" -v s="$s" 'BEGIN { x = 2 / (0.449 * 0.449); d = e - x; if (d < 0) d = -d;
    exit !(e != "" && d <= 3 * s + 1e-5 * x) }'
check "behind the back wall: no direct light ($(line 2 1))" [ "$(line 2 1)" = 0 ]
edirect=$e

# ---- full global illumination ---------------------------------------------------
expect_success "sensors with global illumination (-j 2)" \
  "$GC" sensors "$SC" --points "$TMP/pts.txt" --spp 256 -j 2
cp "$TMP/stdout" "$TMP/gi2.txt"
check "one line per point (3)" [ "$(wc -l <"$TMP/stdout")" -eq 3 ]
e=$(line 1 1) s=$(line 1 2)
check "standard error is printed and positive ($s)" awk -v s="$s" 'BEGIN { exit !(s != "" && s + 0 == s && s > 0) }'
check "indirect light adds to direct ($e > $edirect + 3 x $s)" \
  awk -v e="$e" -v d="$edirect" -v s="$s" 'BEGIN { exit !(e != "" && e > d + 3 * s) }'
check "behind the back wall: no light at all, exactly ($(line 2 1) $(line 2 2))" \
  [ "$(line 2 1) $(line 2 2)" = "0 0" ]
check "third point is lit ($(line 3 1))" awk -v e="$(line 3 1)" 'BEGIN { exit !(e != "" && e > 0) }'
expect_success "the same with -j 1" "$GC" sensors "$SC" --points "$TMP/pts.txt" --spp 256 -j 1
check "-j 1 and -j 2 print identical numbers" cmp -s "$TMP/stdout" "$TMP/gi2.txt"
expect_success "the same with --seed 7" "$GC" sensors "$SC" --points "$TMP/pts.txt" --spp 256 -s 7
check "a different seed gives different estimates" differ "$TMP/stdout" "$TMP/gi2.txt"
expect_success "a script frame: panel (index 2)" \
  "$GC" sensors "$SC" "$GI_ROOT/examples/cornell-box/variants.script" --frame 2 \
  --points "$TMP/pts.txt" --spp 64 --max-bounces 0
check "panel light: the floor point is lit ($(line 1 1))" awk -v e="$(line 1 1)" 'BEGIN { exit !(e > 0) }'

# ---- indirect light only (--min-bounces 1) ------------------------------------------
# What gi-relight's gathering points estimate: direct + indirect = everything.
expect_success "sensors, indirect light only (--min-bounces 1)" \
  "$GC" sensors "$SC" --points "$TMP/pts.txt" --spp 256 -j 2 --min-bounces 1
ei=$(line 1 1) si=$(line 1 2)
ef=$(sed -n 1p "$TMP/gi2.txt" | cut -d' ' -f1) sf=$(sed -n 1p "$TMP/gi2.txt" | cut -d' ' -f2)
check "floor: indirect is positive and below the full value ($ei < $ef)" \
  awk -v i="$ei" -v f="$ef" 'BEGIN { exit !(i > 0 && i < f) }'
check "floor: direct + indirect = full within 4 combined stderr ($edirect + $ei vs $ef)" \
  awk -v d="$edirect" -v i="$ei" -v si="$si" -v f="$ef" -v sf="$sf" \
      'BEGIN { x = f - d - i; if (x < 0) x = -x; exit !(x <= 4 * sqrt(si * si + sf * sf) + 1e-6 * f) }'
expect_exit 2 "--min-bounces above --max-bounces exits 2" \
  "$GC" sensors "$SC" --points "$TMP/pts.txt" --min-bounces 2 --max-bounces 1
expect_stderr "--min-bounces 2 is above --max-bounces 1" "the conflict is explained"

# ---- script area lights: E = pi L under a near-infinite Lambertian emitter ------
# A scene of one far-away triangle; a sensor facing up at (10, 0, 10) under
# 2000 m x 2000 m panels of 1 cd/m^2 emitting down (u x v = -y) 1 m and 2 m above.
cat >"$TMP/tri.gltf" <<'EOF'
{"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],
 "meshes":[{"primitives":[{"attributes":{"POSITION":0},"indices":1}]}],
 "accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3"},
              {"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"}],
 "bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":36},{"buffer":0,"byteOffset":36,"byteLength":6}],
 "buffers":[{"byteLength":44,"uri":"data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAAAAABAAIAAAA="}]}
EOF
echo '10 0 10 0 1 0' >"$TMP/up.txt"
PANEL_A='light A area center 10 1 10 u 1000 0 0 v 0 0 1000 luminance 1'
PANEL_B='light B area center 10 2 10 u 1000 0 0 v 0 0 1000 luminance 1'
printf '%s\nframe a\n' "$PANEL_A" >"$TMP/a.script"
printf '%s\n%s\nframe ab\n' "$PANEL_A" "$PANEL_B" >"$TMP/ab.script"
# near_pi E S K: |E - K pi| <= 4 S + 1e-4 K pi
near_pi() { awk -v e="$1" -v s="$2" -v k="$3" 'BEGIN { x = k * 3.14159265358979; d = e - x;
  if (d < 0) d = -d; exit !(e != "" && d <= 4 * s + 1e-4 * x) }'; }
expect_success "one area light above the sensor" "$GC" sensors "$TMP/tri.gltf" "$TMP/a.script" \
  --points "$TMP/up.txt" --spp 8192
check "E = pi L within 4 stderr ($(line 1 1) +- $(line 1 2))" near_pi "$(line 1 1)" "$(line 1 2)" 1
# Area lights are not geometry (gi_pt.h): the lower panel neither shadows nor hides the upper one.
expect_success "two stacked area lights" "$GC" sensors "$TMP/tri.gltf" "$TMP/ab.script" \
  --points "$TMP/up.txt" --spp 8192
check "stacked area lights add: E = 2 pi L within 4 stderr ($(line 1 1) +- $(line 1 2))" \
  near_pi "$(line 1 1)" "$(line 1 2)" 2
expect_success "one area light above a lone triangle, indirect only" "$GC" sensors "$TMP/tri.gltf" \
  "$TMP/a.script" --points "$TMP/up.txt" --spp 1024 --min-bounces 1
check "nothing bounces back from an open scene: exactly 0 ($(line 1 1) $(line 1 2))" [ "$(line 1 1) $(line 1 2)" = "0 0" ]

# ---- bad points files ------------------------------------------------------------
: >"$TMP/empty.txt"
expect_exit 3 "empty points file exits 3" "$GC" sensors "$SC" --points "$TMP/empty.txt"
expect_stderr "empty\.txt: no points" "empty file: message says no points"
check "nothing on stdout" test ! -s "$TMP/stdout"
printf '# only a comment\n\n' >"$TMP/comments.txt"
expect_exit 3 "comments only exits 3" "$GC" sensors "$SC" --points "$TMP/comments.txt"
expect_stderr "comments\.txt: no points" "comments only: message says no points"
printf '0 0.1 0 0 1 0\n\n1 2 3 4 5\n' >"$TMP/five.txt"
expect_exit 3 "a line with 5 numbers exits 3" "$GC" sensors "$SC" --points "$TMP/five.txt"
expect_stderr "five\.txt:3:10: expected 6 numbers .*number 6 is missing" "5 numbers: file:line:column"
printf '0 0.1 x 0 1 0\n' >"$TMP/word.txt"
expect_exit 3 "a non-number exits 3" "$GC" sensors "$SC" --points "$TMP/word.txt"
expect_stderr "word\.txt:1:7: expected 6 numbers .*number 3 is missing or bad" "non-number: file:line:column"
printf '0 0.1 0 0 1 0 7\n' >"$TMP/seven.txt"
expect_exit 3 "a line with 7 numbers exits 3" "$GC" sensors "$SC" --points "$TMP/seven.txt"
expect_stderr "seven\.txt:1:15: unexpected '7' after 6 numbers" "7 numbers: file:line:column, on one line"
printf '0 0.1 0 1 0 0\n0.2 0.1 0.2 0 0 0\n' >"$TMP/zero.txt"
expect_exit 3 "a zero normal exits 3" "$GC" sensors "$SC" --points "$TMP/zero.txt"
expect_stderr "zero\.txt:2: the normal is the zero vector" "zero normal: file:line"
printf '0 nan 0 0 1 0\n' >"$TMP/nan.txt"
expect_exit 3 "a NaN coordinate exits 3" "$GC" sensors "$SC" --points "$TMP/nan.txt"
expect_exit 4 "missing points file exits 4" "$GC" sensors "$SC" --points "$TMP/none.txt"
expect_stderr "none\.txt: cannot open: No such file" "missing points file is named"

# ---- usage -------------------------------------------------------------------------
expect_exit 2 "missing --points exits 2" "$GC" sensors "$SC"
expect_stderr "missing --points" "missing --points is explained"
expect_exit 2 "--spp 1 exits 2 (a standard error needs 2 samples)" \
  "$GC" sensors "$SC" --points "$TMP/pts.txt" --spp 1
expect_exit 2 "no SCENE exits 2" "$GC" sensors --points "$TMP/pts.txt"
expect_exit 4 "missing scene exits 4" "$GC" sensors "$TMP/none.gltf" --points "$TMP/pts.txt"
expect_exit 0 "--help exits 0" "$GC" sensors --help
expect_stdout "^usage: gi-compare sensors SCENE \[SCRIPT\] --points FILE" "--help prints usage on stdout"

finish
