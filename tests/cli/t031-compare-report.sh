#!/usr/bin/env bash
# t031-compare-report.sh - gi-compare report: Markdown tables, equal-error ratios
# by log-log interpolation, gnuplot plot and script, CSV validation, no partial output.
source "$(dirname "$0")/lib.sh"
GC=$BIN/gi-compare
MK=${BUILD:-$GI_ROOT/build}/tools/mkimage
if [ ! -x "$GC" ]; then
  echo "ok 1 # skip gi-compare not built"
  exit 0
fi
if ! command -v gnuplot >/dev/null; then
  echo "ok 1 # skip gnuplot not on PATH (apt-get install gnuplot-nox)"
  exit 0
fi

cat >"$TMP/runs.csv" <<'EOF'
scene,method,parameters,seconds,nrmse
cornell,relight,"photons=1e5,rays=64",0.09,0.031
cornell,relight,"photons=1e4,rays=16",0.03,0.08
cornell,relight,"photons=1e6,rays=256",0.5,0.012
cornell,path tracing,spp=64,10,0.1
cornell,path tracing,spp=16,2.5,0.2
cornell,path tracing,spp=256,41,0.05
cornell,path tracing,spp=1024,160,0.025

sponza,relight,"say ""hi"", twice",0.2,0.05
sponza,relight,a|b,0.8,0.02
EOF
R=$TMP/rep
expect_success "report from a valid CSV" "$GC" report -o "$R" "$TMP/runs.csv"
for f in report.md report.gp error_vs_time.dat error_vs_time.png error_vs_time.svg; do
  check "writes $f" [ -s "$R/$f" ]
done
check "no staging directory left" [ -z "$(ls -A "$R" | grep -v -E '^(report\.(md|gp)|error_vs_time\.(dat|png|svg))$')" ]
md=$R/report.md
check "one section per scene" [ "$(grep -c '^## Scene: ' "$md")" -eq 2 ]
check "table header" grep -q '^| method | parameters | seconds | nrmse |$' "$md"
check "quoted parameters with commas kept whole" grep -qF '| relight | photons=1e5,rays=64 | 0.09 | 0.031 |' "$md"
check "doubled quotes unescaped" grep -qF '| relight | say "hi", twice | 0.2 | 0.05 |' "$md"
check "pipe escaped in table cell" grep -qF '| relight | a\|b | 0.8 | 0.02 |' "$md"
order=$(grep -E '^\| (path tracing|relight) \|' "$md" | head -7 | awk -F' [|] ' '{ printf "%s/%s ", $1, $3 }')
check "rows sorted by method then seconds" \
  [ "$order" = "| path tracing/2.5 | path tracing/10 | path tracing/41 | path tracing/160 | relight/0.03 | relight/0.09 | relight/0.5 " ]
# expected time of path tracing at nrmse 0.031: log-log interpolation between (41, 0.05) and (160, 0.025)
want=$(awk 'BEGIN { f = log(0.031 / 0.05) / log(0.025 / 0.05); t = exp(log(41) + f * (log(160) - log(41)));
  printf "%.3g s at that error (\342\211\210%.0f\303\227)", t, t / 0.09 }')
check "equal-error ratio interpolated on log-log curves ($want)" \
  grep -qF "relight reaches nrmse 0.031 in 0.09 s; path tracing needs $want" "$md"
check "error outside the other curve: not reached" \
  grep -qF "relight reaches nrmse 0.012 in 0.5 s; path tracing: not reached" "$md"
check "single-method scene says so" grep -q "Only one method" "$md"
check "plot is a PNG" [ "$(head -c 8 "$R/error_vs_time.png" | od -An -tx1 | tr -d ' \n')" = 89504e470d0a1a0a ]
if [ -x "$MK" ]; then
  check "plot size" [ "$("$MK" -i "$R/error_vs_time.png")" = "960 600 3" ] || [ "$("$MK" -i "$R/error_vs_time.png")" = "960 600 4" ]
fi
check "plot as SVG" grep -q '<svg' "$R/error_vs_time.svg"
check "gnuplot script has log-log axes" grep -q '^set logscale xy' "$R/report.gp"
check "axis labels" grep -q "time per frame (s)" "$R/report.gp"
check "y axis label" grep -q "nrmse vs reference" "$R/report.gp"
check "one series per scene and method" [ "$(grep -c "index [0-9]* using 1:2 with linespoints" "$R/report.gp")" -eq 3 ]
check "data blocks sorted by time" \
  [ "$(grep -v '^#' "$R/error_vs_time.dat" | awk 'NF { print $1 }' | head -4 | tr '\n' ' ')" = "2.5 10 41 160 " ]
rm -f "$R/error_vs_time.png"
check "re-plot from DIR with gnuplot report.gp" bash -c "cd '$R' && gnuplot report.gp 2>/dev/null && test -s error_vs_time.png"

# columns in another order, extra column, CRLF line ends, a multi-line quoted field
printf 'nrmse,Seconds,scene,method,parameters,notes\r\n0.5,1,s,m,"two\r\nlines",x\r\n0.25,4,s,m,p,y\r\n' >"$TMP/crlf.csv"
expect_success "header by name, CRLF, multi-line field" "$GC" report -o "$TMP/rep2" "$TMP/crlf.csv"
check "multi-line field on one table line" grep -qF '| m | two  lines | 1 | 0.5 |' "$TMP/rep2/report.md"

# malformed rows: exit 3 naming file:line, nothing written
bad() { # bad NAME LINE MESSAGE-PATTERN CSV-TEXT
  printf '%b' "$4" >"$TMP/$1.csv"
  expect_exit 3 "$1: exit 3" "$GC" report -o "$TMP/out-$1" "$TMP/$1.csv"
  expect_stderr "$1\.csv:$2: $3" "$1: message names $1.csv:$2 and says what was expected"
  check "$1: no output directory contents" [ -z "$(ls -A "$TMP/out-$1" 2>/dev/null)" ]
}
bad badnum 3 'field 4 \(seconds\): expected a positive finite number, got .abc.' \
  'scene,method,parameters,seconds,nrmse\na,b,c,1,0.1\na,b,c,abc,0.1\n'
bad fields 4 'expected 5 fields' 'scene,method,parameters,seconds,nrmse\na,b,c,1,0.1\n\na,b,c,d,1,0.1\n'
bad multiline 4 'field 5 \(nrmse\)' 'scene,method,parameters,seconds,nrmse\na,b,"x\ny",1,0.1\na,b,c,2,-0.1\n'
bad unterminated 3 'unterminated quoted field \(opened on line 2\)' 'scene,method,parameters,seconds,nrmse\na,b,"c,1,0.1\n'
bad header 1 "header: expected columns .*'nrmse' is missing" 'scene,method,parameters,seconds\na,b,c,1\n'
bad emptyname 2 'field 1 \(scene\): expected a name' 'scene,method,parameters,seconds,nrmse\n,b,c,1,0.1\n'
bad zero 2 'field 5 \(nrmse\)' 'scene,method,parameters,seconds,nrmse\na,b,c,1,0\n'
bad strayquote 2 "quote inside an unquoted field" 'scene,method,parameters,seconds,nrmse\na,b,c"d,1,0.5\n'
printf 'scene,method,parameters,seconds,nrmse\n' >"$TMP/norows.csv"
expect_exit 3 "header only: exit 3" "$GC" report -o "$TMP/out-norows" "$TMP/norows.csv"
expect_stderr "no data rows" "header only: explained"

# environment and usage
expect_exit 4 "missing CSV exits 4" "$GC" report -o "$TMP/out-missing" "$TMP/nope.csv"
expect_stderr "nope.csv: cannot open" "missing CSV is named"
expect_exit 4 "gnuplot absent from PATH exits 4" env PATH=/nonexistent "$GC" report -o "$TMP/out-nognuplot" "$TMP/runs.csv"
expect_stderr "gnuplot not found on PATH" "missing gnuplot is explained"
check "nothing written without gnuplot" [ ! -e "$TMP/out-nognuplot" ]
mkdir -p "$TMP/fakebin"
printf '#!/bin/sh\necho "report.gp line 1: simulated failure" >&2\nexit 1\n' >"$TMP/fakebin/gnuplot"
chmod +x "$TMP/fakebin/gnuplot"
expect_exit 4 "failing gnuplot exits 4" env PATH="$TMP/fakebin:$PATH" "$GC" report -o "$TMP/out-fail" "$TMP/runs.csv"
expect_stderr "simulated failure" "gnuplot's message is passed on"
check "failing gnuplot leaves the directory empty" [ -z "$(ls -A "$TMP/out-fail")" ]
expect_exit 2 "missing -o is a usage error" "$GC" report "$TMP/runs.csv"
expect_exit 2 "two CSV files is a usage error" "$GC" report -o "$R" "$TMP/runs.csv" "$TMP/runs.csv"
: >"$TMP/afile"
expect_exit 4 "-o naming a file exits 4" "$GC" report -o "$TMP/afile" "$TMP/runs.csv"

finish
