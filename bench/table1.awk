# bench/table1.awk - medians of gi-relight --timings CSV files (one per run of the
# same script) in the layout of Table 1 of Yue et al. 2007.
#
#   awk -f table1.awk -v mode=MODE [-v paper=P] [-v label=L] run1.csv run2.csv ...
#
# mode=frames  Markdown table: per frame, the median over runs of every stage (ms).
# mode=table1  Markdown table: rows T_di T_pe T_hvds T_fg T_splat T_tot (medians over
#              all runs of the frames that moved a light: changed == "lights"), T_light
#              (= T_tot), T_view (t_total of camera-only frames), T_mat (t_total of
#              material-only frames), then gi's extra stages; beside the paper's figures
#              P = "di,pe,hvds,fg,splat,tot,light,view,mat" (ms) when given.
# mode=totals  CSV name,changed,median t_total_ms per frame.
# mode=stage   the stage (by the row names of table1, e.g. v=T_di) value only: -v row=T_di
# Columns are found by name in each file's header, so their order may change.
# Exit 1 if no file has a data row or a needed column is missing.

BEGIN { FS = ","; nframes = 0; bad = 0 }

FNR == 1 {
    delete col
    for (i = 1; i <= NF; i++) col[$i] = i
    split("frame name changed t_direct_ms t_photon_energies_ms t_hvds_ms t_final_gather_ms " \
          "t_splat_ms t_materials_ms t_gbuffer_ms t_total_ms", need, " ")
    for (k in need) if (!(need[k] in col)) {
        printf "table1.awk: %s: no column %s\n", FILENAME, need[k] > "/dev/stderr"; bad = 1; exit 1
    }
    next
}

{
    f = $(col["frame"]) + 0
    if (!(f in fname)) { fname[f] = $(col["name"]); fchanged[f] = $(col["changed"]); if (f + 1 > nframes) nframes = f + 1 }
    for (k = 1; k <= NST; k++) {
        c = stcol[k]; v = $(col[c]) + 0
        fv[f, c, ++fn[f, c]] = v
        cat = $(col["changed"])
        pv[cat, c, ++pn[cat, c]] = v
        if (f == 0) { pv["first", c, ++pn["first", c]] = v }
    }
    rows++
}

function median(arr, key, n,    i, j, t, a) {
    if (n == 0) return "";
    for (i = 1; i <= n; i++) a[i] = arr[key, i]
    for (i = 2; i <= n; i++) { t = a[i]; for (j = i - 1; j >= 1 && a[j] > t; j--) a[j + 1] = a[j]; a[j + 1] = t }
    if (n % 2) return a[(n + 1) / 2]
    return (a[n / 2] + a[n / 2 + 1]) / 2
}
function fmt(v) { return v == "" ? "n/a" : sprintf("%.1f", v) }
function pmed(cat, c) { return median(pv, cat SUBSEP c, pn[cat, c]) }

BEGIN {
    NST = split("t_direct_ms t_photon_energies_ms t_hvds_ms t_final_gather_ms t_splat_ms " \
                "t_materials_ms t_gbuffer_ms t_total_ms", stcol, " ")
    split("direct photon-energies hvds final-gather splat materials G-buffer total", sthead, " ")
}

END {
    if (bad) exit 1
    if (rows == 0) { print "table1.awk: no timing rows" > "/dev/stderr"; exit 1 }
    if (mode == "frames") {
        printf "| # | frame | changed |"
        for (k = 1; k <= NST; k++) printf " %s |", sthead[k]
        printf "\n|---:|---|---|"
        for (k = 1; k <= NST; k++) printf "---:|"
        printf "\n"
        for (f = 0; f < nframes; f++) {
            if (!(f in fname)) continue
            printf "| %d | %s | %s |", f, fname[f], fchanged[f]
            for (k = 1; k <= NST; k++) printf " %s |", fmt(median(fv, f SUBSEP stcol[k], fn[f, stcol[k]]))
            printf "\n"
        }
    } else if (mode == "totals") {
        print "name,changed,t_total_ms"
        for (f = 0; f < nframes; f++)
            if (f in fname)
                printf "%s,%s,%s\n", fname[f], fchanged[f], median(fv, f SUBSEP "t_total_ms", fn[f, "t_total_ms"])
    } else if (mode == "table1" || mode == "stage") {
        np = split(paper, P, ",")
        L = "lights"
        name[1] = "T_di";    val[1] = pmed(L, "t_direct_ms");             what[1] = "direct light (light-move frames)"
        name[2] = "T_pe";    val[2] = pmed(L, "t_photon_energies_ms");    what[2] = "photon energies"
        name[3] = "T_hvds";  val[3] = pmed(L, "t_hvds_ms");               what[3] = "HVDS (scatter + sum up the levels)"
        name[4] = "T_fg";    val[4] = pmed(L, "t_final_gather_ms");       what[4] = "final gather"
        name[5] = "T_splat"; val[5] = pmed(L, "t_splat_ms");              what[5] = "splat / screen-space indirect"
        name[6] = "T_tot";   val[6] = pmed(L, "t_total_ms");              what[6] = "total of a light-move frame"
        name[7] = "T_light"; val[7] = val[6];                             what[7] = "frame after a light move"
        name[8] = "T_view";  val[8] = pmed("camera", "t_total_ms");       what[8] = "frame after a camera move"
        name[9] = "T_mat";   val[9] = pmed("materials", "t_total_ms");    what[9] = "frame after a material change"
        name[10] = "(T_mat: materials stage)"; val[10] = pmed("materials", "t_materials_ms"); what[10] = "gi only: reflectance factors of the changed material"
        name[11] = "(T_view: G-buffer stage)"; val[11] = pmed("camera", "t_gbuffer_ms"); what[11] = "gi only: G-buffer after a camera move"
        name[12] = "(first frame)"; val[12] = pmed("first", "t_total_ms"); what[12] = "gi only: frame 0, every stage, GL start-up included"
        if (mode == "stage") {
            for (i = 1; i <= 12; i++) if (name[i] == row) { print (val[i] == "" ? "nan" : val[i]); exit 0 }
            exit 1
        }
        printf "| row | %s | paper (GeForce 7800 GTX) | what |\n|---|---:|---:|---|\n", (label == "" ? "gi (ms, median)" : label)
        for (i = 1; i <= 12; i++)
            printf "| %s | %s | %s | %s |\n", name[i], fmt(val[i]), (i <= np && P[i] != "" ? P[i] : ""), what[i]
    } else {
        print "table1.awk: mode must be frames, table1, totals or stage" > "/dev/stderr"; exit 1
    }
}
