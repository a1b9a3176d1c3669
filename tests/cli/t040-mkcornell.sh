#!/usr/bin/env bash
# t040-mkcornell.sh - the Cornell box generator: a scene that gi-compare info
# loads with the expected contents, byte-identical across runs, and no file
# left behind when the output cannot be written.
source "$(dirname "$0")/lib.sh"
GC=$BIN/gi-compare
MC=${BUILD:-$GI_ROOT/build}/tools/mkcornell
if [ ! -x "$GC" ] || [ ! -x "$MC" ]; then
  echo "ok 1 # skip gi-compare or build/tools/mkcornell not built"
  exit 0
fi

expect_success "mkcornell writes the scene" "$MC" "$TMP/a.gltf"
check "the file exists and is not empty" test -s "$TMP/a.gltf"
expect_stderr "wrote .*a\.gltf: 30 triangles, 7 materials, 1 light, 1 camera" "summary line on stderr"
check "nothing on stdout" test ! -s "$TMP/stdout"

expect_success "gi-compare info loads it" "$GC" info "$TMP/a.gltf"
cp "$TMP/stdout" "$TMP/a.json"
check "no loader warnings" grep -q '"warnings": \[\]' "$TMP/a.json"
if command -v python3 >/dev/null; then
  # q EXPR: a Python expression on the parsed JSON d.
  q() { python3 -c "import json,sys; d=json.load(open(sys.argv[1])); print($1)" "$TMP/a.json"; }
  check "30 triangles" [ "$(q "d['triangles']")" = 30 ]
  check "7 materials" [ "$(q "len(d['materials'])")" = 7 ]
  check "material names" [ "$(q "' '.join(sorted(m['name'] for m in d['materials']))")" = \
    "BackWall Ceiling Floor LeftWall RightWall ShortBlock TallBlock" ]
  check "1 light, a point light named ceiling" [ "$(q "[(l['name'], l['type']) for l in d['lights']]")" = "[('ceiling', 'point')]" ]
  check "1 camera" [ "$(q "len(d['cameras'])")" = 1 ]
  check "the box is 0.556 m wide, about 0.55 m high and deep" \
    [ "$(q "' '.join('%.3f' % v for v in d['bbox']['max'])")" = "0.556 0.549 0.559" ]
else
  check "30 triangles" grep -q '"triangles": 30,' "$TMP/a.json"
  check "7 materials" [ "$(grep -c '{"name": "[A-Za-z]*", "base_color"' "$TMP/a.json")" -eq 7 ]
  check "1 point light" [ "$(grep -c '"type": "point"' "$TMP/a.json")" -eq 1 ]
  check "... named ceiling" grep -q '{"name": "ceiling", "type": "point"' "$TMP/a.json"
  check "1 camera" [ "$(grep -c '"yfov_deg"' "$TMP/a.json")" -eq 1 ]
fi

expect_success "a second run" "$MC" -q "$TMP/b.gltf"
check "the two files are byte-identical" cmp -s "$TMP/a.gltf" "$TMP/b.gltf"
check "-q prints nothing" test ! -s "$TMP/stderr"
expect_success "a third run over an existing file" "$MC" -q "$TMP/b.gltf"
check "overwriting gives the same bytes" cmp -s "$TMP/a.gltf" "$TMP/b.gltf"

expect_exit 4 "a missing output directory exits 4 (system failure)" "$MC" "$TMP/no/such/c.gltf"
expect_stderr "no/such/c\.gltf" "the output path is named"
check "no file and no directory were created" test ! -e "$TMP/no"
check "no temporary file left anywhere" [ -z "$(find "$TMP" -name 'c.gltf*' -print -quit)" ]
expect_exit 2 "no output argument exits 2" "$MC"
expect_exit 2 "two output arguments exit 2" "$MC" "$TMP/x.gltf" "$TMP/y.gltf"
check "... and write nothing" test ! -e "$TMP/x.gltf" -a ! -e "$TMP/y.gltf"
expect_exit 0 "--help exits 0" "$MC" --help
expect_stdout "^usage: mkcornell" "--help prints usage on stdout"

finish
