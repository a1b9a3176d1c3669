# bench/ratios.awk - the "Speed at equal error" lines of gi-compare report's report.md
# as tab-separated rows, so the summary reuses report's interpolation instead of
# redoing it:
#
#   scene  method  nrmse(%.3g)  seconds(%.3g)  other_method  other_seconds  ratio
#
# other_seconds is "-" and ratio "not reached (...)" when the other curve does not
# span the error. Lines look like
#   - relight reaches nrmse 0.031 in 0.09 s; path tracing needs 105 s at that error (≈1165×)
#   - relight reaches nrmse 0.012 in 0.5 s; path tracing: not reached (its nrmse spans ...)

BEGIN { OFS = "\t" }

/^## Scene: / { scene = substr($0, 11); next }

/^- .* reaches nrmse .* in .* s; / {
    line = substr($0, 3)
    i = index(line, " reaches nrmse ")
    method = substr(line, 1, i - 1)
    rest = substr(line, i + length(" reaches nrmse "))
    split(rest, w, " ")
    e = w[1]; t = w[3]
    j = index(rest, " s; ")
    tail = substr(rest, j + 4)
    k = index(tail, " needs ")
    if (k > 0) {
        other = substr(tail, 1, k - 1)
        after = substr(tail, k + 7)
        split(after, v, " ")
        ot = v[1]
        p = index(after, "(")
        ratio = substr(after, p + 1)
        sub(/\)$/, "", ratio)
    } else {
        k = index(tail, ": not reached")
        other = substr(tail, 1, k - 1)
        ot = "-"
        ratio = substr(tail, k + 2)
    }
    print scene, method, e, t, other, ot, ratio
}
