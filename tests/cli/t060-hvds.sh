#!/usr/bin/env bash
# t060-hvds.sh - gi-hvds from the command line on a small Cornell box: the .gih
# is written and reported, identical for any -j, records its inputs; k-means
# selection works and selects another number of points; and the exit codes of
# every refusal: usage 2, missing scene or .gip 4, a .gip of another scene or a
# truncated one 3, output into a missing directory 4 with nothing written.
source "$(dirname "$0")/lib.sh"
GH=$BIN/gi-hvds
GP=$BIN/gi-precompute
MK=${BUILD:-$GI_ROOT/build}/tools/mkcornell
if [ ! -x "$GH" ] || [ ! -x "$GP" ] || [ ! -x "$MK" ]; then
  echo "ok 1 # skip gi-hvds, gi-precompute or mkcornell not built"
  exit 0
fi
"$MK" -q "$TMP/c.gltf" || { not_ok "mkcornell makes the scene"; finish; }
"$GP" "$TMP/c.gltf" -o "$TMP/c.gip" --photons 50000 -q || { not_ok "gi-precompute makes the .gip"; finish; }
SMALL=(--gather-rays 16 --r-max 0.05)

# gpoints: the gathering-point count of the last run's summary (stderr).
gpoints() { sed -n 's/.*: \([0-9][0-9]*\) gathering points (.*/\1/p' "$TMP/stderr"; }
# no_tmp_files: no '*.tmp.*' file anywhere under $TMP.
no_tmp_files() { [ -z "$(find "$TMP" -name '*.tmp.*' -print -quit)" ]; }

# ---- help and version ---------------------------------------------------------------
expect_success "--help exits 0" "$GH" --help
expect_stdout '^usage: gi-hvds SCENE SCENE\.gip -o SCENE\.gih' "--help prints the usage on stdout"
expect_stdout 'default auto' "--help gives the gathering-ray default"
check "--help writes nothing on stderr" test ! -s "$TMP/stderr"
expect_success "--version exits 0" "$GH" --version
expect_stdout '^gi-hvds [0-9]' "--version names the tool"

# ---- usage errors (exit 2, nothing written) ---------------------------------------------
X=$TMP/x.gih
expect_exit 2 "unknown option" "$GH" "$TMP/c.gltf" "$TMP/c.gip" -o "$X" --bogus
expect_stderr "bogus" "the unknown option is named"
expect_stderr "try 'gi-hvds --help'" "a usage error points at --help"
expect_exit 2 "--gather foo" "$GH" "$TMP/c.gltf" "$TMP/c.gip" -o "$X" --gather foo
expect_stderr "--gather: expected 'rejection' or 'kmeans', got 'foo'" "the bad --gather value is quoted"
expect_exit 2 "--r-min larger than --r-max" "$GH" "$TMP/c.gltf" "$TMP/c.gip" -o "$X" --r-min 0.1 --r-max 0.05
expect_stderr "--r-min 0.1 is larger than --r-max 0.05" "both radii are named"
expect_exit 2 "--gather-rays 0" "$GH" "$TMP/c.gltf" "$TMP/c.gip" -o "$X" --gather-rays 0
expect_stderr "--gather-rays: 0 is out of range" "the range error names the option"
expect_exit 2 "--gather-rays not a number" "$GH" "$TMP/c.gltf" "$TMP/c.gip" -o "$X" --gather-rays 16x
expect_exit 2 "--r-max negative" "$GH" "$TMP/c.gltf" "$TMP/c.gip" -o "$X" --r-max -1
expect_exit 2 "--key-photons negative" "$GH" "$TMP/c.gltf" "$TMP/c.gip" -o "$X" --key-photons -1
expect_exit 2 "missing -o" "$GH" "$TMP/c.gltf" "$TMP/c.gip"
expect_stderr "missing -o" "missing -o is explained"
expect_exit 2 "one positional argument" "$GH" "$TMP/c.gltf" -o "$X"
expect_stderr "expected SCENE and SCENE\.gip, got 1 arguments" "the argument count is given"
expect_exit 2 "three positional arguments" "$GH" "$TMP/c.gltf" "$TMP/c.gip" "$TMP/c.gip" -o "$X"
check "no output after usage errors" test ! -e "$X"

# ---- the Cornell box ----------------------------------------------------------------------
expect_success "the Cornell box builds (-j 2)" "$GH" "$TMP/c.gltf" "$TMP/c.gip" -o "$TMP/c.gih" "${SMALL[@]}" -j 2
check "the .gih exists" test -s "$TMP/c.gih"
check "nothing on stdout" test ! -s "$TMP/stdout"
n_rej=$(gpoints)
expect_stderr "[0-9]+ gathering points \(rejection\), [0-9]+ gathering rays -> [0-9]+ \(key, count\) pairs" \
  "summary: gathering points, rays and pairs"
expect_stderr "octree: [0-9]+ nodes, depth [0-9]+, leaves per level .*; [0-9]+ keys" "summary: octree and keys"
size=$(stat -c %s "$TMP/c.gih")
expect_stderr "c\.gih: $size bytes" "the output and its size ($size bytes) are reported"
rays=$(sed -n 's/.* gathering points ([a-z-]*), \([0-9]*\) gathering rays.*/\1/p' "$TMP/stderr")
check "16 rays per gathering point ($n_rej points, $rays rays)" test "$rays" = "$((16 * n_rej))"
check "the .gih starts with its magic" test "$(head -c 6 "$TMP/c.gih")" = GIHVDS
check "META records the tool" grep -aq "tool=gi-hvds" "$TMP/c.gih"
check "META records the options" grep -aq "option.gather-rays=16" "$TMP/c.gih"
check "META records the scene" grep -aq "input.scene=$TMP/c.gltf" "$TMP/c.gih"
check "META records the .gip" grep -aq "input.gip=$TMP/c.gip" "$TMP/c.gih"
check "META records the .gip's hash" grep -aqE "input.gip.hash=[0-9a-f]{16}" "$TMP/c.gih"

expect_success "the same with -j 1" "$GH" "$TMP/c.gltf" "$TMP/c.gip" -o "$TMP/c1.gih" "${SMALL[@]}" -j 1
check "-j 1 and -j 2 give identical bytes" cmp -s "$TMP/c.gih" "$TMP/c1.gih"
expect_success "-q is quiet" "$GH" "$TMP/c.gltf" "$TMP/c.gip" -o "$TMP/cq.gih" "${SMALL[@]}" -q
check "-q: empty stderr" test ! -s "$TMP/stderr"
check "-q does not change the bytes" cmp -s "$TMP/c.gih" "$TMP/cq.gih"
expect_success "another seed" "$GH" "$TMP/c.gltf" "$TMP/c.gip" -o "$TMP/cs.gih" "${SMALL[@]}" -s 2
check "another seed gives other bytes" bash -c "! cmp -s '$TMP/c.gih' '$TMP/cs.gih'"
expect_success "a larger --r-max" "$GH" "$TMP/c.gltf" "$TMP/c.gip" -o "$TMP/cr.gih" --gather-rays 16 --r-max 0.1
n_big=$(gpoints)
check "a larger --r-max selects fewer points ($n_big < $n_rej)" test "${n_big:-0}" -gt 0 -a "${n_big:-0}" -lt "$n_rej"

# --key-photons: a count no key reaches sends every ray to the root's keys (one per normal bin)
pairs() { sed -n 's/.* -> \([0-9]*\) (key, count) pairs.*/\1/p' "$TMP/stderr"; }
lifted() { sed -n 's/.*, \([0-9]*\) to coarser keys.*/\1/p' "$TMP/stderr"; }
expect_success "--key-photons 0" "$GH" "$TMP/c.gltf" "$TMP/c.gip" -o "$TMP/k0.gih" "${SMALL[@]}" --key-photons 0
p0=$(pairs) l0=$(lifted)
check "--key-photons 0 moves no ray ($l0)" test "$l0" = 0
check "META records --key-photons 0" grep -aq "option.key-photons=0" "$TMP/k0.gih"
check "the default records --key-photons 8" grep -aq "option.key-photons=8" "$TMP/c.gih"
expect_success "--key-photons 1000000" "$GH" "$TMP/c.gltf" "$TMP/c.gip" -o "$TMP/kbig.gih" "${SMALL[@]}" --key-photons 1000000
pb=$(pairs) lb=$(lifted)
check "--key-photons 1000000 moves rays ($lb) and merges pairs ($pb < $p0)" \
  test "${lb:-0}" -gt 0 -a "${pb:-0}" -gt 0 -a "${pb:-0}" -lt "${p0:-0}"
check "... into at most one key per normal bin and point ($pb <= 26 x $n_rej)" test "${pb:-0}" -le $((26 * n_rej))

expect_success "--gather kmeans" "$GH" "$TMP/c.gltf" "$TMP/c.gip" -o "$TMP/ck.gih" "${SMALL[@]}" --gather kmeans
expect_stderr "gathering points \(k-means\)" "the summary names k-means"
n_km=$(gpoints)
check "k-means selects another number of points (rejection $n_rej, k-means $n_km)" \
  test "${n_km:-0}" -gt 0 -a "${n_km:-0}" -ne "$n_rej"
check "META records --gather kmeans" grep -aq "option.gather=kmeans" "$TMP/ck.gih"
expect_success "an existing output is replaced" "$GH" "$TMP/c.gltf" "$TMP/c.gip" -o "$TMP/ck.gih" "${SMALL[@]}"
check "... by the new result" cmp -s "$TMP/c.gih" "$TMP/ck.gih"

# ---- input errors ---------------------------------------------------------------------------
expect_exit 4 "missing scene (exit 4)" "$GH" "$TMP/none.gltf" "$TMP/c.gip" -o "$X" "${SMALL[@]}"
expect_stderr "none\.gltf" "the missing scene is named"
expect_exit 4 "missing .gip (exit 4)" "$GH" "$TMP/c.gltf" "$TMP/none.gip" -o "$X" "${SMALL[@]}"
expect_stderr "none\.gip: No such file" "the missing .gip is named"

# Another scene: the tall block moved by 1 mm (a node translation), so its geometry hash differs.
sed 's/{"name":"TallBlock","mesh":6}/{"name":"TallBlock","mesh":6,"translation":[0.001,0,0]}/' \
  "$TMP/c.gltf" >"$TMP/d.gltf"
check "the second scene differs from the first" bash -c "! cmp -s '$TMP/c.gltf' '$TMP/d.gltf'"
"$GP" "$TMP/d.gltf" -o "$TMP/d.gip" --photons 20000 -q
expect_exit 3 "a .gip of another scene (exit 3)" "$GH" "$TMP/c.gltf" "$TMP/d.gip" -o "$X" "${SMALL[@]}"
expect_stderr "d\.gip: section 'META': made from scene hash [0-9a-f]{16}, but the scene given has [0-9a-f]{16} \(re-run gi-precompute\)" \
  "the message names the .gip and says what to re-run"
expect_exit 3 "the scene of a .gip swapped the other way (exit 3)" "$GH" "$TMP/d.gltf" "$TMP/c.gip" -o "$X" "${SMALL[@]}"
head -c 100000 "$TMP/c.gip" >"$TMP/trunc.gip"
expect_exit 3 "a truncated .gip (exit 3)" "$GH" "$TMP/c.gltf" "$TMP/trunc.gip" -o "$X" "${SMALL[@]}"
expect_stderr "trunc\.gip: truncated" "the truncated .gip is named"
expect_exit 3 "a .gih given as the .gip (exit 3)" "$GH" "$TMP/c.gltf" "$TMP/c.gih" -o "$X" "${SMALL[@]}"
expect_stderr "c\.gih: is a \.gih file" "the wrong file type is explained"
check "no output after input errors" test ! -e "$X"

expect_exit 4 "output into a missing directory (exit 4)" \
  "$GH" "$TMP/c.gltf" "$TMP/c.gip" -o "$TMP/nodir/x.gih" "${SMALL[@]}"
expect_stderr "nodir/x\.gih" "the output path is named"
check "nothing written for a missing directory" test ! -e "$TMP/nodir"
check "no temporary file left anywhere" no_tmp_files
finish
