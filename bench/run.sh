#!/usr/bin/env bash
# bench/run.sh - `make bench`: speed against error of the gi pipeline against the path
# tracer, on the Cornell box (examples/cornell-box) and, when present, the Sponza atrium
# (../shared/scenes/sponza). See bench/README.md for what is measured and how.
#
# Environment: BIN (tools, default bin), BUILD (build dir, default build; work files go
# to $BUILD/bench), BENCH_QUICK=1 (smoke run: tiny images, few samples, 2 sweep
# settings), BENCH_SCENES (default "cornell-box sponza"), BENCH_THREADS (default 2),
# BENCH_RUNS (relight runs for the medians, default 3, at least 1).
# Writes bench/results/ (summary.md, runs.csv, report.md and plots, raw/), caches the
# path-traced references in bench/cache/. Exit status: 0, or that of the first stage
# that failed (the other stages still run where they can).
set -uo pipefail

BENCH_DIR=$(cd "$(dirname "$0")" && pwd)
ROOT=$(cd "$BENCH_DIR/.." && pwd)
BIN=$(cd "${BIN:-$ROOT/bin}" && pwd)
BUILD=$(cd "${BUILD:-$ROOT/build}" && pwd)
RESULTS=$BENCH_DIR/results
CACHE=$BENCH_DIR/cache
WORK=$BUILD/bench
case "${BENCH_QUICK:-0}" in 0|"") QUICK=0 ;; *) QUICK=1 ;; esac
THREADS=${BENCH_THREADS:-2}
RUNS=${BENCH_RUNS:-3}
SCENES=${BENCH_SCENES:-cornell-box sponza}
[ "$RUNS" -ge 1 ] 2>/dev/null || { echo "bench: BENCH_RUNS must be a positive integer" >&2; exit 2; }

export MESA_SHADER_CACHE_DISABLE=true LP_NUM_THREADS=$THREADS
export LC_ALL=C

source "$BENCH_DIR/lib.sh"

for t in gi-precompute gi-hvds gi-relight gi-compare; do
  [ -x "$BIN/$t" ] || { echo "bench: $BIN/$t: missing (run make)" >&2; exit 4; }
done
# Work on a copy of the tools: a `make` during the bench (colleagues share the tree)
# must not mix two builds in one table.
mkdir -p "$BUILD/bench/bin"
for t in gi-precompute gi-hvds gi-relight gi-compare; do
  cp -f "$BIN/$t" "$BUILD/bench/bin/$t.tmp" && mv -f "$BUILD/bench/bin/$t.tmp" "$BUILD/bench/bin/$t" ||
    { echo "bench: cannot copy $BIN/$t to $BUILD/bench/bin" >&2; exit 4; }
done
BIN=$BUILD/bench/bin
for t in iinfo gnuplot sha256sum; do
  command -v "$t" >/dev/null || { echo "bench: $t: not on PATH (make deps)" >&2; exit 4; }
done

# ---- settings ----------------------------------------------------------------------
# shellcheck disable=SC2034  # read indirectly (${!name}) by bench_scene
# Per scene: frames compared with the path tracer, reference spp, path-tracer curve,
# spp of the cheap second-seed image that measures the reference's noise, the options
# every run gets, and the sweep. Sweep entries: "default" or PARAM=VALUE with PARAM one
# of photons, rmax-div (r-max = scene diagonal / VALUE), rays, cells.
if [ "$QUICK" = 1 ]; then
  W=160; H=120
  CB_FRAMES="point-lowered camera-moved"; CB_REF_SPP=32; CB_PT_SPPS="2 8 32"; CB_NOISE_SPP=2
  CB_PC_BASE="--photons 100000"; CB_HV_BASE="--gather-rays 64"
  CB_SWEEP="default photons=50000"
  SP_FRAMES="sun-moved"; SP_REF_SPP=8; SP_PT_SPPS="1 4 16"; SP_NOISE_SPP=1
  SP_PC_BASE="--photons 100000"; SP_HV_BASE="--gather-rays 16"
  SP_SWEEP="default photons=50000"
else
  W=640; H=480
  CB_FRAMES="point-lowered blue-left-wall camera-moved"; CB_REF_SPP=512; CB_PT_SPPS="16 64 256"
  CB_NOISE_SPP=64
  CB_PC_BASE=""; CB_HV_BASE=""
  CB_SWEEP="default photons=250000 photons=4000000 rmax-div=128 rmax-div=256 rays=64 rays=1024 cells=4 cells=64"
  SP_FRAMES="sun-moved arcade-moved"; SP_REF_SPP=512; SP_PT_SPPS="4 16 64"; SP_NOISE_SPP=64
  SP_PC_BASE=""; SP_HV_BASE=""
  SP_SWEEP="default photons=250000 photons=4000000 rmax-div=128 rmax-div=256 rays=64"
fi
# Tool defaults (gi-precompute --help, gi-hvds --help), for the parameter columns.
DEF_PHOTONS=1000000; DEF_RMAXDIV=181; DEF_RAYS=auto; DEF_CELLS=16
# shellcheck disable=SC2034  # read indirectly
# Paper, Table 1 (ms; GeForce 7800 GTX): T_di T_pe T_hvds T_fg T_splat T_tot T_light T_view T_mat
PAPER_cornell_box="6,11,11,5,76,109,109,87,1271"
# shellcheck disable=SC2034  # read indirectly
PAPER_sponza="15,15,12,27,122,191,191,164,1310"

PT_HASH=$(pt_hash)
T_START=$(date +%s)
LOAD_START=$(cut -d' ' -f1-3 /proc/loadavg)
mkdir -p "$RESULTS" "$CACHE" "$WORK"
# nothing stale may survive a failed stage
rm -rf "$RESULTS/raw"
rm -f "$RESULTS"/{summary.md,runs.csv,frames.csv,report.md,report.gp,error_vs_time.png,error_vs_time.svg,error_vs_time.dat}
RAW=$RESULTS/raw
mkdir -p "$RAW"
RUNS_CSV=$RESULTS/runs.csv
ERR_CSV=$RESULTS/frames.csv
echo "scene,method,parameters,seconds,nrmse,frames,precompute_s,hvds_s,gip_bytes,gih_bytes" > "$RUNS_CSV"
echo "scene,method,parameters,frame,changed,seconds,nrmse" > "$ERR_CSV"

say "mode $([ "$QUICK" = 1 ] && echo quick || echo full): ${W}x${H}, $THREADS threads, $RUNS relight runs;" \
    "results in $RESULTS, references cached in $CACHE"

# ---- one scene -----------------------------------------------------------------------

# value of a setting's parameter, or the baseline's
setting_value() { # SETTING PARAM BASEVALUE
  case "$1" in "$2"=*) echo "${1#*=}" ;; *) echo "$3" ;; esac
}

# bench_scene NAME GLTF SCRIPT PREFIX: everything for one scene. PREFIX selects the
# settings above (CB or SP).
bench_scene() {
  local name=$1 gltf=$2 src_script=$3 pfx=$4
  local frames_v=${pfx}_FRAMES ref_v=${pfx}_REF_SPP pt_v=${pfx}_PT_SPPS noise_v=${pfx}_NOISE_SPP
  local pcb_v=${pfx}_PC_BASE hvb_v=${pfx}_HV_BASE sweep_v=${pfx}_SWEEP
  local frames=${!frames_v} ref_spp=${!ref_v} pt_spps=${!pt_v} noise_spp=${!noise_v}
  local pc_base=${!pcb_v} hv_base=${!hvb_v} sweep=${!sweep_v}
  local wk=$WORK/$name raw=$RAW/$name
  rm -rf "$wk"; mkdir -p "$wk" "$raw"
  say "== $name"

  # The script at the bench's size: every `resolution` line replaced.
  local script=$wk/variants.script
  sed -E "s/^([[:space:]]*)resolution[[:space:]].*/\1resolution $W $H/" "$src_script" > "$script"
  grep -q "^[[:space:]]*resolution $W $H" "$script" || sed -i "1i resolution $W $H" "$script"
  cp "$script" "$raw/variants.script"
  local f
  for f in $frames; do
    grep -qE "^[[:space:]]*frame[[:space:]]+$f([[:space:]]|$)" "$script" ||
      { bench_fail 2 "$name: frame '$f' is not in $src_script"; return 1; }
  done
  local shash diag
  shash=$(scene_hash "$gltf")
  "$BIN/gi-compare" info "$gltf" > "$raw/scene.json" 2>"$raw/info.log" ||
    { bench_fail $? "$name: gi-compare info $gltf"; return 1; }
  diag=$(tr -d '\n ' < "$raw/scene.json" | grep -o '"bbox":{"min":\[[^]]*\],"max":\[[^]]*\]' |
         tr -c '0-9.eE+,-' ' ' | awk -F'[ ,]+' '{ n = 0; for (i = 1; i <= NF; i++) if ($i != "") v[++n] = $i;
           printf "%.6g", sqrt((v[4]-v[1])^2 + (v[5]-v[2])^2 + (v[6]-v[3])^2) }')
  echo "$diag" > "$raw/diagonal"

  # -- 1. precompute and hvds at default settings: time, peak memory, sizes
  local gip=$wk/default.gip gih=$wk/default.gih
  # shellcheck disable=SC2086
  if measure "$raw/precompute.log" "$BIN/gi-precompute" "$gltf" -o "$gip" -j "$THREADS" $pc_base; then :; else
    bench_fail $? "$name: gi-precompute (log $raw/precompute.log)"; return 1
  fi
  local pc_s=$M_SEC pc_kb=$M_KB
  # shellcheck disable=SC2086
  if measure "$raw/hvds.log" "$BIN/gi-hvds" "$gltf" "$gip" -o "$gih" -j "$THREADS" $hv_base; then :; else
    bench_fail $? "$name: gi-hvds (log $raw/hvds.log)"; return 1
  fi
  local hv_s=$M_SEC hv_kb=$M_KB
  local pl=$raw/precompute.log hl=$raw/hvds.log
  {
    echo "tool,wall_s,peak_rss_kib,output_bytes"
    echo "gi-precompute,$pc_s,$pc_kb,$(fsize "$gip")"
    echo "gi-hvds,$hv_s,$hv_kb,$(fsize "$gih")"
  } > "$raw/precompute.csv"
  {
    echo "| stage | wall s | peak RSS MB | output | details (from the tool's summary) |"
    echo "|---|---:|---:|---|---|"
    echo "| gi-precompute | $pc_s | $(mb $((pc_kb * 1024))) | .gip $(mb "$(fsize "$gip")") MB |" \
         "$(grab "$pl" '[0-9]+ entry points') entry points, $(grab "$pl" '[0-9]+ photons,') photons;" \
         "$(grab "$pl" 'compact [0-9.]+ B/photon') B/photon compact (read every frame)," \
         "$(grab "$pl" 'detail [0-9.]+ B/photon') B/photon detail |"
    echo "| gi-hvds | $hv_s | $(mb $((hv_kb * 1024))) | .gih $(mb "$(fsize "$gih")") MB |" \
         "$(grab "$hl" '[0-9]+ gathering points') gathering points, $(grab "$hl" '[0-9]+ gathering rays') gathering rays," \
         "$(grab "$hl" '[0-9]+ keys') keys; $(grab "$hl" 'per photon [0-9.]+') B/photon (key)," \
         "$(grab "$hl" 'per gathering ray [0-9.]+') B/gathering ray |"
  } > "$raw/precompute.md"
  for v in "entry points" "photons," "B/photon" "per gathering ray"; do
    grep -q "$v" "$pl" "$hl" || say "$name: warning: no '$v' in the tools' summaries (format changed?)"
  done

  # -- 2. relight of the variant script, RUNS times: medians per stage
  local r tfiles=() rl_kb=0 rl_ok=1
  for ((r = 1; r <= RUNS; r++)); do
    rm -rf "$wk/default"
    if measure "$raw/relight-run$r.log" "$BIN/gi-relight" "$gltf" "$gip" "$gih" "$script" \
         -o "$wk/default" -j "$THREADS" --timings "$raw/timings-run$r.csv"; then
      tfiles+=("$raw/timings-run$r.csv")
      [ "$M_KB" -gt "$rl_kb" ] && rl_kb=$M_KB
      echo "$M_SEC" >> "$raw/relight-wall.txt"
    else
      bench_fail $? "$name: gi-relight run $r (log $raw/relight-run$r.log)"; rl_ok=0
    fi
  done
  [ "$rl_ok" = 1 ] || return 1
  echo "gi-relight,$(sort -n "$raw/relight-wall.txt" | tail -n 1),$rl_kb,$(du -sb "$wk/default" | cut -f1)" >> "$raw/precompute.csv"
  echo "| gi-relight (whole script, slowest of $RUNS runs) | $(sort -n "$raw/relight-wall.txt" | tail -n 1) |" \
       "$(mb $((rl_kb * 1024))) | $(ls "$wk/default"/*.exr | wc -l) EXR frames | loading, GL set-up and every frame of the script |" >> "$raw/precompute.md"
  local pv=PAPER_${name//-/_}
  awk -f "$BENCH_DIR/table1.awk" -v mode=table1 -v paper="${!pv:-}" "${tfiles[@]}" > "$raw/table1.md" &&
  awk -f "$BENCH_DIR/table1.awk" -v mode=frames "${tfiles[@]}" > "$raw/frames.md" &&
  awk -f "$BENCH_DIR/table1.awk" -v mode=totals "${tfiles[@]}" > "$raw/totals.csv" ||
    { bench_fail 3 "$name: timings CSV of gi-relight unreadable"; return 1; }

  # -- 3. references (cached) and the second-seed images that measure their noise
  local key img ok_refs=1
  for f in $frames; do
    key=$(cache_key "$shash" "$script" "$f" "${W}x$H" "$ref_spp" 1)
    img=$CACHE/ref-$name-$f-$key.exr
    if [ ! -f "$img" ]; then
      say "$name: reference '$f' (${W}x$H, $ref_spp spp) is not cached: rendering it once"
      if "$BIN/gi-compare" render "$gltf" "$script" --frame "$f" --spp "$ref_spp" --size "${W}x$H" \
           -s 1 -j "$THREADS" -q -o "$img" 2>"$raw/ref-$f.log"; then :; else
        bench_fail $? "$name: reference '$f' (log $raw/ref-$f.log)"; ok_refs=0; continue
      fi
    fi
    ln -sf "$img" "$wk/ref-$f.exr"
    key=$(cache_key "$shash" "$script" "$f" "${W}x$H" "$noise_spp" 3)
    img=$CACHE/seed3-$name-$f-$key.exr
    if [ ! -f "$img" ]; then
      "$BIN/gi-compare" render "$gltf" "$script" --frame "$f" --spp "$noise_spp" --size "${W}x$H" \
        -s 3 -j "$THREADS" -q -o "$img" 2>"$raw/seed3-$f.log" ||
        bench_fail $? "$name: second-seed image '$f' (log $raw/seed3-$f.log)"
    fi
    [ -f "$img" ] && ln -sf "$img" "$wk/seed3-$f.exr"
  done
  [ "$ok_refs" = 1 ] || return 1

  # frames_eval DIR TOTALS_CSV METHOD PARAMS PCS HVS GIP GIH: diff DIR/F.exr for the
  # compared frames, append per-frame rows and the mean row.
  frames_eval() {
    local dir=$1 totals=$2 method=$3 params=$4 pcs=$5 hvs=$6 gipb=$7 gihb=$8
    local ff e t ch es=() ts=() bad=0
    for ff in $frames; do
      e=$(nrmse "$dir/$ff.exr" "$wk/ref-$ff.exr")
      t=$(awk -F, -v n="$ff" '$1 == n { printf "%.6g", $3 / 1000 }' "$totals")
      ch=$(awk -F, -v n="$ff" '$1 == n { print $2 }' "$totals")
      if [ -z "$e" ] || [ -z "$t" ]; then bad=1; continue; fi
      echo "$name,$method,$params,$ff,$ch,$t,$e" >> "$ERR_CSV"
      es+=("$e"); ts+=("$t")
    done
    [ "$bad" = 0 ] || return 3
    echo "$name,$method,$params,$(printf '%s\n' "${ts[@]}" | mean_of),$(printf '%s\n' "${es[@]}" | mean_of),$(echo $frames | tr ' ' '+'),$pcs,$hvs,$gipb,$gihb" >> "$RUNS_CSV"
  }

  # -- 4. the sweep over the relight's quality parameters (one relight run per setting;
  #       the default setting's times are the medians of step 2)
  local base_photons base_rays base_cells
  base_photons=$(echo "$pc_base" | grep -oE -- '--photons [0-9]+' | awk '{print $2}'); base_photons=${base_photons:-$DEF_PHOTONS}
  base_rays=$(echo "$hv_base" | grep -oE -- '--gather-rays [0-9]+' | awk '{print $2}'); base_rays=${base_rays:-$DEF_RAYS}
  base_cells=$(echo "$hv_base" | grep -oE -- '--cell-photons [0-9]+' | awk '{print $2}'); base_cells=${base_cells:-$DEF_CELLS}
  local methods=() s
  for s in $sweep; do
    case "$s" in
      default) ;;
      photons=*) methods+=("relight photons") ;;
      rmax-div=*) methods+=("relight r-max") ;;
      rays=*) methods+=("relight gather-rays") ;;
      cells=*) methods+=("relight cell-photons") ;;
      *) bench_fail 2 "$name: unknown sweep setting '$s'"; continue ;;
    esac
  done
  [ ${#methods[@]} -gt 0 ] || methods=("relight")
  local uniq_methods
  uniq_methods=$(printf '%s\n' "${methods[@]}" | awk '!seen[$0]++')
  local i=0 ph rd ry ce params sgip sgih spcs shvs
  for s in $sweep; do
    i=$((i + 1))
    ph=$(setting_value "$s" photons "$base_photons"); rd=$(setting_value "$s" rmax-div "$DEF_RMAXDIV")
    ry=$(setting_value "$s" rays "$base_rays"); ce=$(setting_value "$s" cells "$base_cells")
    params="photons=$ph r-max=diag/$rd gather-rays=$ry cell-photons=$ce"
    [ "$s" = default ] && params="$params (default)"
    if [ "$s" = default ]; then
      local m
      while IFS= read -r m; do
        frames_eval "$wk/default" "$raw/totals.csv" "$m" "$params" "$pc_s" "$hv_s" "$(fsize "$gip")" "$(fsize "$gih")" ||
          bench_fail $? "$name: default setting: nrmse of the compared frames"
      done <<< "$uniq_methods"
      continue
    fi
    say "$name: sweep $s"
    local sd=$wk/sweep-$i; mkdir -p "$sd"
    sgip=$gip; spcs=$pc_s
    case "$s" in
      photons=*)
        local pcb
        pcb=$(echo "$pc_base" | sed -E 's/--photons [0-9]+//')
        # shellcheck disable=SC2086
        measure "$raw/sweep-$i-precompute.log" "$BIN/gi-precompute" "$gltf" -o "$sd/s.gip" -j "$THREADS" \
            $pcb --photons "$ph" || { bench_fail $? "$name: sweep $s: gi-precompute"; continue; }
        sgip=$sd/s.gip; spcs=$M_SEC ;;
    esac
    local hva=()
    [ "$rd" != "$DEF_RMAXDIV" ] && hva+=(--r-max "$(calc "$diag / $rd")")
    [ "$ry" != "$DEF_RAYS" ] && hva+=(--gather-rays "$ry")
    [ "$ce" != "$DEF_CELLS" ] && hva+=(--cell-photons "$ce")
    measure "$raw/sweep-$i-hvds.log" "$BIN/gi-hvds" "$gltf" "$sgip" -o "$sd/s.gih" -j "$THREADS" "${hva[@]}" ||
      { bench_fail $? "$name: sweep $s: gi-hvds"; continue; }
    shvs=$M_SEC; sgih=$sd/s.gih
    measure "$raw/sweep-$i-relight.log" "$BIN/gi-relight" "$gltf" "$sgip" "$sgih" "$script" -o "$sd/out" \
        -j "$THREADS" --timings "$raw/sweep-$i-timings.csv" ||
      { bench_fail $? "$name: sweep $s: gi-relight"; continue; }
    awk -f "$BENCH_DIR/table1.awk" -v mode=totals "$raw/sweep-$i-timings.csv" > "$raw/sweep-$i-totals.csv" ||
      { bench_fail 3 "$name: sweep $s: timings"; continue; }
    local method
    case "$s" in
      photons=*) method="relight photons" ;; rmax-div=*) method="relight r-max" ;;
      rays=*) method="relight gather-rays" ;; cells=*) method="relight cell-photons" ;;
    esac
    frames_eval "$sd/out" "$raw/sweep-$i-totals.csv" "$method" "$params" "$spcs" "$shvs" \
        "$(fsize "$sgip")" "$(fsize "$sgih")" || bench_fail $? "$name: sweep $s: nrmse"
    # the big files of a setting are not needed any more
    rm -f "$sd/s.gip" "$sd/s.gih"
  done

  # -- 5. the path tracer's own curve: the same frames at increasing spp (seed 2, so
  #       independent of the seed-1 reference)
  local spp pe pt
  for spp in $pt_spps; do
    say "$name: path tracing at $spp spp"
    local es=() ts=() okc=1
    for f in $frames; do
      img=$wk/pt-$f-$spp.exr
      if "$BIN/gi-compare" render "$gltf" "$script" --frame "$f" --spp "$spp" --size "${W}x$H" \
           -s 2 -j "$THREADS" -q -o "$img" 2>"$raw/pt-$f-$spp.log"; then :; else
        bench_fail $? "$name: path tracing '$f' at $spp spp (log $raw/pt-$f-$spp.log)"; okc=0; continue
      fi
      pt=$(exr_attr "$img" gi:seconds)
      pe=$(nrmse "$img" "$wk/ref-$f.exr")
      if [ -z "$pt" ] || [ -z "$pe" ]; then bench_fail 3 "$name: path tracing '$f' at $spp spp: no time or nrmse"; okc=0; continue; fi
      echo "$name,path tracing,spp=$spp,$f,-,$pt,$pe" >> "$ERR_CSV"
      es+=("$pe"); ts+=("$pt")
    done
    [ "$okc" = 1 ] &&
      echo "$name,path tracing,spp=$spp,$(printf '%s\n' "${ts[@]}" | mean_of),$(printf '%s\n' "${es[@]}" | mean_of),$(echo $frames | tr ' ' '+'),,,," >> "$RUNS_CSV"
  done

  # -- 6. the reference's own noise: seed 2 against seed 3 at noise_spp spp; each image
  #       carries 1/sqrt(2) of their mutual nrmse, the reference sqrt(noise_spp/ref_spp) of that.
  {
    echo "| frame | reference seconds | mutual nrmse, seeds 2 and 3 at $noise_spp spp | estimated noise of the $ref_spp-spp reference | the reference's own estimate (gi:noise_nrmse) |"
    echo "|---|---:|---:|---:|---:|"
    for f in $frames; do
      local m="n/a" rn="n/a" rs
      rs=$(exr_attr "$wk/ref-$f.exr" gi:seconds)
      if [ -f "$wk/seed3-$f.exr" ] && [ -f "$wk/pt-$f-$noise_spp.exr" ]; then
        m=$(nrmse "$wk/pt-$f-$noise_spp.exr" "$wk/seed3-$f.exr")
        [ -n "$m" ] && rn=$(calc "$m / sqrt(2) * sqrt($noise_spp / $ref_spp)") || m="n/a"
      fi
      echo "| $f | ${rs:-?} | $m | $rn | $(exr_attr "$wk/ref-$f.exr" gi:noise_nrmse || true) |"
      [ "$rn" != "n/a" ] && echo "$rn" >> "$raw/refnoise.txt"
    done
  } > "$raw/refnoise.md"

  # -- what the summary needs
  {
    echo "scene_file=$gltf"
    echo "scene_hash=$shash"
    echo "frames=$frames"
    echo "ref_spp=$ref_spp"
    echo "pt_spps=$pt_spps"
    echo "noise_spp=$noise_spp"
    echo "ref_noise_mean=$( [ -f "$raw/refnoise.txt" ] && mean_of < "$raw/refnoise.txt" || echo nan)"
    echo "sweep=$sweep"
    echo "pc_base=$pc_base"
    echo "hv_base=$hv_base"
  } > "$raw/meta.txt"
  return 0
}

# ---- the scenes ----------------------------------------------------------------------
DONE_SCENES=()
for sc in $SCENES; do
  case "$sc" in
    cornell-box)
      mkdir -p "$WORK/scenes"
      if [ ! -x "$BUILD/tools/mkcornell" ]; then bench_fail 4 "$BUILD/tools/mkcornell: missing (run make)"; continue; fi
      if "$BUILD/tools/mkcornell" "$WORK/scenes/cornell-box.gltf" >/dev/null 2>"$WORK/scenes/mkcornell.log"; then :; else
        bench_fail $? "mkcornell (log $WORK/scenes/mkcornell.log)"; continue
      fi
      bench_scene cornell-box "$WORK/scenes/cornell-box.gltf" "$ROOT/examples/cornell-box/variants.script" CB &&
        DONE_SCENES+=(cornell-box) ;;
    sponza)
      sp=$ROOT/../shared/scenes/sponza/sponza.gltf
      if [ ! -f "$sp" ]; then
        say "sponza: $sp is absent: skipping this scene"; continue
      fi
      bench_scene sponza "$(cd "$(dirname "$sp")" && pwd)/sponza.gltf" "$ROOT/examples/sponza/variants.script" SP &&
        DONE_SCENES+=(sponza) ;;
    *) bench_fail 2 "unknown scene '$sc' in BENCH_SCENES (cornell-box, sponza)" ;;
  esac
done

# ---- report and summary ------------------------------------------------------------------
if [ "$(wc -l < "$RUNS_CSV")" -le 1 ]; then
  bench_fail 3 "no runs to report"
else
  say "gi-compare report $RUNS_CSV -o $RESULTS"
  if "$BIN/gi-compare" report -q -o "$RESULTS" "$RUNS_CSV" 2>"$RAW/report.log"; then
    awk -f "$BENCH_DIR/ratios.awk" "$RESULTS/report.md" > "$RAW/ratios.tsv"
  else
    bench_fail $? "gi-compare report (log $RAW/report.log)"
  fi
fi
touch "$RAW/ratios.tsv"

T_END=$(date +%s)
LOAD_END=$(cut -d' ' -f1-3 /proc/loadavg)
SUMMARY=$RESULTS/summary.md
BENCH_MODE=$([ "$QUICK" = 1 ] && echo "quick (BENCH_QUICK=1: a smoke run, the numbers mean nothing)" || echo full)
BENCH_BIN=$BIN
export W H THREADS RUNS BENCH_MODE BENCH_BIN
"$BENCH_DIR/summary.sh" "$RESULTS" "$((T_END - T_START))" "$LOAD_START" "$LOAD_END" "${DONE_SCENES[*]:-}" \
  "${BENCH_FAILS[@]+"${BENCH_FAILS[@]}"}" > "$SUMMARY.tmp" && mv "$SUMMARY.tmp" "$SUMMARY" ||
  bench_fail 4 "writing $SUMMARY"

say "done in $((T_END - T_START)) s: $SUMMARY, $RESULTS/report.md, $RESULTS/error_vs_time.png"
if [ "$BENCH_RC" -ne 0 ]; then
  say "${#BENCH_FAILS[@]} stage(s) failed:"
  printf '  %s\n' "${BENCH_FAILS[@]}" >&2
fi
exit "$BENCH_RC"
