#!/usr/bin/env bash
# bench/summary.sh RESULTS ELAPSED_S LOAD_START LOAD_END "SCENES" [FAILURE...] - writes
# summary.md of a bench run on stdout from RESULTS/runs.csv, RESULTS/raw/ (made by
# bench/run.sh) and the equal-error ratios gi-compare report wrote into report.md.
# Environment (from run.sh): W, H, THREADS, RUNS, BENCH_MODE.
set -uo pipefail
res=$1 elapsed=$2 load0=$3 load1=$4 scenes=$5
shift 5
raw=$res/raw
export LC_ALL=C

cpu=$(awk -F': *' '/^model name/ { print $2; exit }' /proc/cpuinfo)
mem=$(awk '/^MemTotal/ { printf "%.1f GB", $2 / 1048576 }' /proc/meminfo)
commit=$(git -C "$(dirname "$0")/.." rev-parse --short HEAD 2>/dev/null || echo unknown)
dirty=$(git -C "$(dirname "$0")/.." status --porcelain --untracked-files=no 2>/dev/null | grep -q . && echo " (with uncommitted changes)")

# net NRMSE NOISE: sqrt(nrmse^2 - noise^2), "<noise" when below it, "?" without a noise figure
net() {
  awk -v e="$1" -v r="$2" 'BEGIN { if (r == "nan" || r == "") { print "?"; exit }
    d = e * e - r * r; if (d <= 0) print "< noise"; else printf "%.4f", sqrt(d) }'
}

# the row of ratios.tsv for a run of runs.csv: "seconds_other<TAB>ratio" or nothing
# ratio_of SCENE METHOD SECONDS NRMSE
ratio_of() {
  awk -F'\t' -v s="$1" -v m="$2" -v t="$3" -v e="$4" '
    BEGIN { te = sprintf("%.3g", e); tt = sprintf("%.3g", t) }
    $1 == s && $2 == m && $3 == te && $4 == tt && $5 == "path tracing" { print $6 "\t" $7; exit }' \
    "$raw/ratios.tsv"
}

# extrapolate SCENE NRMSE NOISE RELIGHT_SECONDS: the path tracer's time at an error below its
# measured curve, from its lowest-error point on the Monte Carlo law (error ~ 1/sqrt(spp), so
# time ~ error^-2). Two figures: on the measured errors (conservative: the reference's noise
# flattens the measured curve, so the law underestimates the time) and on the net errors
# (reference noise removed from both). Prints "s_measured<TAB>ratio<TAB>s_net<TAB>ratio<TAB>spp",
# the net pair "-" without a usable noise figure; nothing when the error is not below the curve.
extrapolate() {
  awk -F, -v s="$1" -v e="$2" -v n="$3" -v tr="$4" '
    $1 == s && $2 == "path tracing" && (best == "" || $5 + 0 < best) { best = $5 + 0; bt = $4 + 0; bs = $3 }
    END {
      if (best == "" || e >= best || e <= 0 || tr <= 0) exit
      tc = bt * best * best / (e * e); sub(/^spp=/, "", bs)
      tn = "-"; rn = "-"
      if (n != "" && n != "nan") {
        dm = best * best - n * n; de = e * e - n * n
        if (dm > 0 && de > 0) { tn = sprintf("%.3g", bt * dm / de); rn = sprintf("%.0f", bt * dm / de / tr) }
      }
      printf "%.3g\t%.0f\t%s\t%s\t%s\n", tc, tc / tr, tn, rn, bs
    }' "$res/runs.csv"
}

echo "# gi benchmark: speed against error"
echo
echo "- date: $(date -u '+%Y-%m-%d %H:%M UTC')"
echo "- mode: $BENCH_MODE"
echo "- machine: $cpu, $(nproc) cores available, $mem RAM; **shared with other users during the run**"
echo "  (load average $load0 at the start, $load1 at the end), so times are noisy"
echo "- every tool ran with $THREADS threads (\`-j $THREADS\`, \`LP_NUM_THREADS=$THREADS\` for llvmpipe); images ${W}x$H"
echo "- gi commit $commit$dirty (tools: \`$("${BENCH_BIN:-bin}/gi-relight" --version 2>&1 | head -n 1)\`, copied before the run); the whole bench took $elapsed s"
echo "- time per frame: gi-relight's \`t_total_ms\` of the frame within its script (what the frame"
echo "  changed is recomputed: light, camera or material), without loading the files; the path"
echo "  tracer's \`gi:seconds\` (its rendering wall time). Both are means over the compared frames, and"
echo "  so is nrmse (rms error / mean of the reference). Precompute and HVDS are not in the frame time."

echo
echo "## Headline"
echo
if [ -z "$scenes" ]; then
  echo "No scene completed."
fi
for sc in $scenes; do
  line=$(awk -F, -v s="$sc" '$1 == s && $3 ~ /\(default\)$/ { print $2 "\t" $4 "\t" $5; exit }' "$res/runs.csv")
  [ -n "$line" ] || { echo "- $sc: no default relight run"; continue; }
  IFS=$'\t' read -r m t e <<< "$line"
  rr=$(ratio_of "$sc" "$m" "$t" "$e")
  ms=$(awk -v t="$t" 'BEGIN { printf "%.0f", t * 1000 }')
  if [ -z "$rr" ]; then
    echo "- **$sc**: a relight frame at default settings takes $ms ms at nrmse $(printf '%.3g' "$e"); no equal-error line in report.md"
  else
    IFS=$'\t' read -r pts ratio <<< "$rr"
    if [ "$pts" = "-" ]; then
      noise_sc=$(sed -n 's/^ref_noise_mean=//p' "$raw/$sc/meta.txt")
      ex=$(extrapolate "$sc" "$e" "$noise_sc" "$t")
      if [ -n "$ex" ]; then
        IFS=$'\t' read -r xs xr xns xnr xspp <<< "$ex"
        net_part=""
        [ "$xns" != "-" ] && net_part=" (≈${xnr}×, ${xns} s, with the reference noise removed from both errors)"
        echo "- **$sc**: a relight frame at default settings takes $ms ms at nrmse $(printf '%.3g' "$e")," \
             "below the path tracer's measured curve ${ratio#not reached }. Extrapolated from its $xspp-spp point" \
             "on the Monte Carlo law (time ∝ error⁻²), the path tracer needs about $xs s per frame" \
             "for that error: **relight ≈${xr}× faster** at equal error$net_part"
      else
        echo "- **$sc**: a relight frame at default settings takes $ms ms at nrmse $(printf '%.3g' "$e"); path tracing $ratio, so no ratio"
      fi
    else
      echo "- **$sc**: a relight frame at default settings takes $ms ms at nrmse $(printf '%.3g' "$e");" \
           "the path tracer needs $pts s per frame for the same nrmse: **relight is $ratio faster** at equal error" \
           "(interpolated by \`gi-compare report\`)"
    fi
  fi
done

for sc in $scenes; do
  d=$raw/$sc
  # shellcheck disable=SC1090
  frames=$(sed -n 's/^frames=//p' "$d/meta.txt"); ref_spp=$(sed -n 's/^ref_spp=//p' "$d/meta.txt")
  noise=$(sed -n 's/^ref_noise_mean=//p' "$d/meta.txt"); pcb=$(sed -n 's/^pc_base=//p' "$d/meta.txt")
  hvb=$(sed -n 's/^hv_base=//p' "$d/meta.txt")
  echo
  echo "## $sc"
  echo
  echo "Scene \`$(sed -n 's/^scene_file=//p' "$d/meta.txt" | sed "s|.*/\(.*/.*\)$|\1|")\` (content hash $(sed -n 's/^scene_hash=//p' "$d/meta.txt"),"\
       "diagonal $(cat "$d/diagonal") m), script \`raw/$sc/variants.script\` (the example's, at ${W}x$H)."
  base="the tools' defaults"
  [ -n "$pcb$hvb" ] && base="$base, except gi-precompute \`${pcb:-(none)}\` and gi-hvds \`${hvb:-(none)}\`"
  echo "Frames compared with the path tracer: $frames. Baseline (\"default\") settings: $base."
  echo
  echo "### Precompute and HVDS at default settings"
  echo
  cat "$d/precompute.md"
  echo
  echo "### Relight: the layout of the paper's Table 1 (median of $RUNS runs, ms)"
  echo
  cat "$d/table1.md"
  echo
  dom=$(awk -F'|' 'NR > 2 && NR <= 7 { gsub(/ /, "", $2); v = $3 + 0; if (v > best) { best = v; n = $2 } }
                  END { if (n != "") printf "%s (%.0f ms)", n, best }' "$d/table1.md")
  tot=$(awk -F'|' '$2 ~ /T_tot/ { printf "%.0f", $3 }' "$d/table1.md")
  echo "The largest stage of a light-move frame: $dom of $tot ms."
  echo
  echo "<details><summary>Every frame (median of $RUNS runs, ms)</summary>"
  echo
  cat "$d/frames.md"
  echo
  echo "</details>"
  echo
  echo "### Sweep of the relight's quality parameters"
  echo
  echo "One parameter at a time from the default; time and nrmse are means over the compared frames."
  echo "\"path tracing\" is the path tracer's time per frame at the same nrmse (interpolated on its curve;"
  echo "below its lowest measured error, extrapolated from that point as time ∝ error⁻² on the measured errors)."
  echo
  echo "\"net\" is sqrt(nrmse² − reference noise²), the error against the exact image (see the reference below)."
  echo
  echo "| method | parameters | precompute s | hvds s | .gip MB | .gih MB | relight ms/frame | nrmse | net | path tracing s | speed-up |"
  echo "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
  awk -F, -v s="$sc" '$1 == s && $2 != "path tracing" { print }' "$res/runs.csv" |
  awk -F, '!seen[$3]++' |
  while IFS=, read -r _ m p t e _ pcs hvs gb hb; do
    rr=$(ratio_of "$sc" "$m" "$t" "$e")
    IFS=$'\t' read -r pts ratio <<< "${rr:-$'?\t?'}"
    if [ "$pts" = "-" ]; then
      ex=$(extrapolate "$sc" "$e" "$noise" "$t")
      if [ -n "$ex" ]; then
        IFS=$'\t' read -r xs xr _ <<< "$ex"
        pts="≈$xs (extrapolated)"; ratio="≈${xr}×"
      else
        pts="not reached"; ratio="-"
      fi
    fi
    printf '| %s | %s | %s | %s | %s | %s | %.1f | %.4f | %s | %s | %s |\n' "$m" "$p" "$pcs" "$hvs" \
      "$(awk -v b="$gb" 'BEGIN { printf "%.1f", b / 1e6 }')" "$(awk -v b="$hb" 'BEGIN { printf "%.1f", b / 1e6 }')" \
      "$(awk -v t="$t" 'BEGIN { print t * 1000 }')" "$e" "$(net "$e" "$noise")" "$pts" "$ratio"
  done
  echo
  echo "### The path tracer (gi-compare render, seed 2, against the seed-1 reference)"
  echo
  echo "| spp | s/frame | nrmse | net |"
  echo "|---:|---:|---:|---:|"
  awk -F, -v s="$sc" '$1 == s && $2 == "path tracing" { sub(/^spp=/, "", $3); print $3, $4, $5 }' "$res/runs.csv" |
  while read -r n t e; do printf '| %s | %.2f | %.4f | %s |\n' "$n" "$t" "$e" "$(net "$e" "$noise")"; done
  echo
  echo "### The reference"
  echo
  echo "$ref_spp spp at ${W}x$H, seed 1, cached in \`bench/cache/\` (rendered once; the time is from that run)."
  echo "Its own noise, estimated from two independent cheap images:"
  echo
  cat "$d/refnoise.md"
  echo
  echo "Mean estimated reference noise: nrmse $noise. Every measured nrmse is about"
  echo "sqrt(true² + reference noise²); both methods carry the same term, so the equal-error"
  echo "crossing (and the speed-up) is unaffected, but errors near that level are floored."
done

# the plot as text, for the README (gnuplot's dumb terminal): per scene, the path tracer's
# curve (P) and every relight run (R), log-log
if command -v gnuplot >/dev/null && [ -f "$res/error_vs_time.dat" ]; then
  echo
  echo "## Plot (text): nrmse against seconds per frame, log-log"
  for sc in $scenes; do
    idx=$(awk -v s="$sc" '/^# index [0-9]+: scene / { i = $3; sub(/:$/, "", i); q = "\047" s "\047";
            if (index($0, "scene " q ", method") && index($0, "path tracing")) p = p " " i;
            else if (index($0, "scene " q ", method")) r = r " " i }
          END { print p "|" r }' "$res/error_vs_time.dat")
    pidx=${idx%%|*} ridx=${idx#*|}
    [ -n "${pidx// /}" ] || continue
    plot="'$res/error_vs_time.dat' index ${pidx# } using 1:2 with linespoints pt 'P' title 'path tracing'"
    for i in $ridx; do plot="$plot, '$res/error_vs_time.dat' index $i using 1:2 with points pt 'R' notitle"; done
    echo
    echo "$sc (R: relight runs of the sweep, P: path tracer):"
    echo
    echo '```'
    gnuplot -e "set terminal dumb size 78,22; set logscale xy; set xlabel 'seconds per frame'; \
                set ylabel 'nrmse'; set key top right; plot $plot" 2>/dev/null | sed 's/[[:space:]]*$//' | sed '/^$/d'
    echo '```'
  done
fi

echo
echo "## Report"
echo
echo "\`report.md\` (all runs and every equal-error ratio), \`error_vs_time.png\` / \`.svg\` (log-log"
echo "nrmse against time per frame), \`runs.csv\` (the runs), \`frames.csv\` (per frame), \`raw/\` (logs,"
echo "timings CSVs of every relight run)."
if [ $# -gt 0 ]; then
  echo
  echo "## Failures"
  echo
  for f in "$@"; do echo "- $f"; done
fi
