#!/usr/bin/env bash
# t050-precompute.sh - gi-precompute from the command line: the Cornell box
# (and Sponza, if present) precompute, the output is identical for any -j,
# the summary is on stderr, and the exit codes: usage 2 (also an unknown
# --fixed-material), missing scene 4, malformed scene 3, output into a missing
# directory 4 with nothing written.
source "$(dirname "$0")/lib.sh"
GP=$BIN/gi-precompute
MK=${BUILD:-$GI_ROOT/build}/tools/mkcornell
if [ ! -x "$GP" ] || [ ! -x "$MK" ]; then
  echo "ok 1 # skip gi-precompute or mkcornell not built"
  exit 0
fi
"$MK" "$TMP/cb.gltf" 2>/dev/null
BOX=$TMP/cb.gltf

# ---- help, version, usage errors ----------------------------------------------
expect_success "--help exits 0" "$GP" --help
expect_stdout 'default 1000000' "--help gives the photon default"
expect_stdout '--region XMIN YMIN ZMIN XMAX YMAX ZMAX' "--help describes --region"
check "--help writes nothing on stderr" test ! -s "$TMP/stderr"
expect_success "--version exits 0" "$GP" --version
expect_stdout '^gi-precompute [0-9]' "--version names the tool"

expect_exit 2 "unknown option" "$GP" "$BOX" -o "$TMP/x.gip" --bogus
expect_stderr "unknown option '--bogus'" "the unknown option is named"
expect_stderr "try" "a usage error points at --help"
expect_exit 2 "no SCENE" "$GP" -o "$TMP/x.gip"
expect_exit 2 "no -o" "$GP" "$BOX"
expect_stderr "missing -o/--output" "missing output named"
expect_exit 2 "two scenes" "$GP" "$BOX" "$BOX" -o "$TMP/x.gip"
expect_exit 2 "--photons not a number" "$GP" "$BOX" -o "$TMP/x.gip" --photons 1e6x
expect_exit 2 "--photons 0" "$GP" "$BOX" -o "$TMP/x.gip" --photons 0
expect_exit 2 "--max-bounces negative" "$GP" "$BOX" -o "$TMP/x.gip" --max-bounces -1
expect_exit 2 "--threads out of range" "$GP" "$BOX" -o "$TMP/x.gip" -j -3
expect_exit 2 "--region with 5 numbers" "$GP" "$BOX" -o "$TMP/x.gip" --region 0 0 0 1 1
expect_exit 2 "--region with a bad number" "$GP" "$BOX" -o "$TMP/x.gip" --region 0 0 0 1 1 z
expect_exit 2 "--region minimum above maximum" "$GP" "$BOX" -o "$TMP/x.gip" --region=0,0,0,1,-1,1
expect_stderr "axis y" "the inverted axis is named"
expect_exit 2 "--region-grid without --region" "$GP" "$BOX" -o "$TMP/x.gip" --region-grid 3
expect_exit 2 "-q with -v" "$GP" "$BOX" -o "$TMP/x.gip" -q -v
expect_exit 2 "-o naming the scene" "$GP" "$BOX" -o "$BOX"
expect_exit 2 "--fixed-material given twice" "$GP" "$BOX" -o "$TMP/x.gip" --fixed-material Floor --fixed-material Floor
expect_exit 2 "unknown --fixed-material (usage, exit 2)" "$GP" "$BOX" -o "$TMP/x.gip" --fixed-material Marble
expect_stderr "no material 'Marble'.*'Floor'" "the message lists the scene's materials"
check "no output after usage errors" test ! -e "$TMP/x.gip"

# ---- input and output errors --------------------------------------------------
expect_exit 4 "missing scene (exit 4)" "$GP" "$TMP/none.gltf" -o "$TMP/x.gip"
expect_stderr "none\.gltf" "the missing scene is named"
printf '{"asset":{"version":"2.0"},"meshes":[{"primitives":[{"attributes":{"POSITION":7}}]}]}' >"$TMP/bad.gltf"
expect_exit 3 "malformed scene (exit 3)" "$GP" "$TMP/bad.gltf" -o "$TMP/x.gip"
expect_exit 4 "output into a missing directory (exit 4)" "$GP" "$BOX" -o "$TMP/nodir/x.gip"
expect_stderr "nodir" "the missing directory is named"
check "nothing written for a missing directory" test ! -e "$TMP/nodir"
check "no partial file anywhere" test -z "$(find "$TMP" -name '*.tmp.*')"

# ---- the Cornell box ------------------------------------------------------------
expect_success "Cornell box precomputes" "$GP" "$BOX" -o "$TMP/cb.gip" --photons 200000 -j 2
expect_stderr "entry points \([0-9]+ uniform" "summary: entry points"
expect_stderr "mean path length [0-9.]+, [0-9.]+% of paths escaped, 0 triangles skipped" \
  "summary: path length, escapes, skipped triangles"
expect_stderr "photons/s.*compact [0-9.]+ B/photon, detail 26.00 B/photon" "summary: speed and bytes per photon"
check "nothing on stdout" test ! -s "$TMP/stdout"
check "the .gip starts with its magic" test "$(head -c 8 "$TMP/cb.gip")" = GIPHOTON
check "META records the scene" grep -aq "input.scene=$BOX" "$TMP/cb.gip"
check "META records the options" grep -aq "option.photons=200000" "$TMP/cb.gip"
photons=$(sed -n 's/.* \([0-9]*\) photons, mean.*/\1/p' "$TMP/stderr")
check "photon count near --photons ($photons)" \
  test "$photons" -gt 180000 -a "$photons" -lt 220000

expect_success "-j 1" "$GP" "$BOX" -o "$TMP/cb1.gip" --photons 200000 -j 1
check "-j 1 and -j 2 give identical bytes" cmp -s "$TMP/cb.gip" "$TMP/cb1.gip"
expect_success "-q is quiet" "$GP" "$BOX" -o "$TMP/cbq.gip" --photons 20000 -q
check "-q: empty stderr" test ! -s "$TMP/stderr"
expect_success "a different seed" "$GP" "$BOX" -o "$TMP/cbs.gip" --photons 200000 -s 2
check "another seed gives other bytes" bash -c "! cmp -s '$TMP/cb.gip' '$TMP/cbs.gip'"

expect_success "--region, --max-bounces 3 and --fixed-material" "$GP" "$BOX" -o "$TMP/cbr.gip" \
  --photons 100000 --region 0.1 0.5 0.1 0.45 0.53 0.45 --max-bounces 3 --fixed-material TallBlock -v
expect_stderr "region: [0-9]+ batches" "-v reports the refinement"
expect_stderr "pilot: 8192 paths" "-v reports the pilot"
check "META records the region" grep -aq "option.region=0.100000001 0.5 0.100000001" "$TMP/cbr.gip"
check "META records the fixed material" grep -aq "option.fixed-material.0=TallBlock" "$TMP/cbr.gip"
expect_success "same with -j 1" "$GP" "$BOX" -o "$TMP/cbr1.gip" \
  --photons 100000 --region=0.1,0.5,0.1,0.45,0.53,0.45 --max-bounces 3 --fixed-material TallBlock -j 1
check "region runs are identical for any -j" cmp -s "$TMP/cbr.gip" "$TMP/cbr1.gip"
expect_success "an existing output is replaced" "$GP" "$BOX" -o "$TMP/cb.gip" --photons 20000
check "no temp file left beside the output" test -z "$(find "$TMP" -name '*.tmp.*')"

# ---- Sponza (smoke run; the timed run is in the benchmark) ------------------------
SP=$SHARED/scenes/sponza/sponza.gltf
if [ -f "$SP" ]; then
  expect_success "Sponza precomputes" "$GP" "$SP" -o "$TMP/sponza.gip" --photons 100000
  expect_stderr "0 triangles skipped" "Sponza: no degenerate triangles"
else
  _n=$((_n + 1)); echo "ok $_n # skip $SP not found"
fi
finish
