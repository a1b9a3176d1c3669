#!/usr/bin/env bash
# t010-scene-info.sh - gi-compare info: the loaded scene as JSON on stdout
# (counts, hash stable across runs and across .gltf/.glb), warnings, and the
# exit codes for a missing file (4), a malformed file (3) and bad usage (2).
source "$(dirname "$0")/lib.sh"
GC=$BIN/gi-compare
if [ ! -x "$GC" ]; then
  echo "ok 1 # skip gi-compare not built"
  exit 0
fi
have_py=0
command -v python3 >/dev/null && have_py=1

# json EXPR FILE: evaluate a Python expression on the parsed JSON `d`.
json() { python3 -c "import json,sys; d=json.load(open(sys.argv[2])); print($1)" "$2" "$2"; }

# A one-triangle scene with an embedded buffer, made here.
BUF="AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAAAAABAAIAAAA="
tiny() {  # tiny POSITION_ACCESSOR MATERIAL_NAME
  cat <<EOF
{"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],
 "meshes":[{"primitives":[{"attributes":{"POSITION":$1},"indices":1,"material":0}]}],
 "materials":[{"name":"$2"}],
 "accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3"},
              {"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"}],
 "bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":36},{"buffer":0,"byteOffset":36,"byteLength":6}],
 "buffers":[{"byteLength":44,"uri":"data:application/octet-stream;base64,$BUF"}]}
EOF
}
tiny 0 'white \"wall\" \\ 1' >"$TMP/tiny.gltf"
tiny 9 wall >"$TMP/bad.gltf"

expect_success "info on a generated one-triangle scene" "$GC" info "$TMP/tiny.gltf"
expect_stdout '"triangles": 1,' "triangle count in the JSON"
expect_stdout '"hash": "[0-9a-f]{16}"' "16-hex-digit hash"
expect_stdout '"surface_area_m2": 0.5' "surface area of the right triangle"
expect_stdout '"name": "white \\"wall\\" \\\\ 1"' "material name escaped in JSON"
if [ $have_py = 1 ]; then
  cp "$TMP/stdout" "$TMP/tiny.json"
  check "stdout is valid JSON" python3 -c "import json,sys; json.load(open(sys.argv[1]))" "$TMP/tiny.json"
fi
check "stderr stays empty" test ! -s "$TMP/stderr"

expect_exit 3 "malformed file is bad data (exit 3)" "$GC" info "$TMP/bad.gltf"
expect_stderr 'bad\.gltf: meshes\[0\]\.primitives\[0\]\.attributes\.POSITION: accessor 9 does not exist' \
  "error names the file and the element"
check "nothing on stdout for a malformed file" test ! -s "$TMP/stdout"
expect_exit 4 "missing file is a system error (exit 4)" "$GC" info "$TMP/none.gltf"
expect_stderr 'none\.gltf: cannot open: No such file or directory' "error names the missing file"
expect_exit 2 "no SCENE argument is a usage error" "$GC" info

S=$SHARED/gltf-samples
if [ -d "$S" ]; then
  expect_success "info Box.gltf" "$GC" info "$S/Box/glTF/Box.gltf"
  cp "$TMP/stdout" "$TMP/box1.json"
  expect_stdout '"triangles": 12,' "Box has 12 triangles"
  "$GC" info "$S/Box/glTF/Box.gltf" >"$TMP/box2.json" 2>/dev/null
  check "same output on a second run" cmp -s "$TMP/box1.json" "$TMP/box2.json"
  "$GC" info "$S/Box/glTF-Binary/Box.glb" >"$TMP/boxb.json" 2>/dev/null
  check "same hash for .gltf and .glb" \
    test "$(grep '"hash"' "$TMP/box1.json")" = "$(grep '"hash"' "$TMP/boxb.json")"
  expect_success "info LightsPunctualLamp" "$GC" info "$S/LightsPunctualLamp/glTF/LightsPunctualLamp.gltf"
  expect_stdout 'unsupported extensions ignored: KHR_materials_transmission' "unsupported extension warned"
  expect_stdout '"intensity_cd": 15' "point light intensity in candela"
  if [ $have_py = 1 ]; then
    cp "$TMP/stdout" "$TMP/lamp.json"
    check "5 point lights" test "$(json 'sum(l["type"] == "point" for l in d["lights"])' "$TMP/lamp.json")" = 5
  fi
else
  _n=$((_n + 1)); echo "ok $_n # skip $S not found"
fi

SP=$SHARED/scenes/sponza/sponza.gltf
if [ -f "$SP" ]; then
  expect_success "info sponza.gltf" "$GC" info "$SP"
  expect_stdout '"triangles": 69063,' "Sponza has 69,063 triangles"
  if [ $have_py = 1 ]; then
    cp "$TMP/stdout" "$TMP/sponza.json"
    check "Sponza has 11 textures" test "$(json 'len(d["textures"])' "$TMP/sponza.json")" = 11
    check "Sponza has 20 materials" test "$(json 'len(d["materials"])' "$TMP/sponza.json")" = 20
  fi
fi
finish
