#!/usr/bin/env bash
# t142-relight-scale: the same room at 10,000 times the size, lit by the same
# lights moved with it (point intensities times the square of the scale), gives
# the same direct light: glTF has no units but metres, and a scene authored in
# millimetres and read as metres is a room kilometres wide. The path tracer's
# frames of both agree within 1e-4 nrmse. The relight's did not (measured
# 2026-12-07 at 48 x 48 as here, direct light against the unscaled box): at
# 10,000 times the G-buffer's depth could not tell the blocks' faces from the
# floor along their feet 8 km away (depth 1 at the near plane of 1 cm, falling
# to a float's last bits far away), 0.034 nrmse on point-lowered and
# camera-moved; at 1,000 times a shadow-edge pixel's points on the wall at
# x = 0 lay behind it by the rounding of the camera's distance, 0.111 on
# fill-light (a column of pixels at half their light). Now within 0.001.
. "$(dirname "$0")/lib.sh"
command -v python3 >/dev/null || { echo "ok 1 # skip python3 missing"; exit 0; }
"$BUILD/tools/mkcornell" -q "$TMP/c1.gltf" || { not_ok "mkcornell makes the scene"; finish; }
# the scene under a root node scaled by s, and variants.script's positions,
# extents and point intensities scaled to match (the near plane left at 1 cm)
cat >"$TMP/scale.py" <<'PY'
import json, re, sys
s = float(sys.argv[1]); src, script, gout, sout = sys.argv[2:6]
g = json.load(open(src))
n = len(g["nodes"])
g["nodes"].append({"name": "root", "scale": [s, s, s], "children": list(g["scenes"][0]["nodes"])})
g["scenes"][0]["nodes"] = [n]
json.dump(g, open(gout, "w"))
num = r"-?[0-9.]+(?:e[-+]?[0-9]+)?"
vec = lambda m: m.group(1) + " " + " ".join("%.9g" % (float(v) * s) for v in m.group(2).split())
out = []
for line in open(script).read().split("\n"):
    if line.startswith("resolution"):
        line = "resolution 48 48"
    line = re.sub(r"\b(position|target|center|u|v) ((?:%s ){2}%s)" % (num, num), vec, line)
    line = re.sub(r"intensity (%s)" % num, lambda m: "intensity %.9g" % (float(m.group(1)) * s * s), line)
    out.append(line)
open(sout, "w").write("\n".join(out))
PY
V=$GI_ROOT/examples/cornell-box/variants.script
for s in 1 1000 10000; do
  check "the scene and script at scale $s" python3 "$TMP/scale.py" $s "$TMP/c1.gltf" "$V" "$TMP/c$s.gltf" "$TMP/v$s.script"
  expect_success "precompute at scale $s" gi-precompute -q "$TMP/c$s.gltf" -o "$TMP/c$s.gip" --photons 100000
  expect_success "hvds at scale $s" gi-hvds -q "$TMP/c$s.gltf" "$TMP/c$s.gip" -o "$TMP/c$s.gih" --gather-rays 64
  # point-lowered (1), camera-moved (5), fill-light (6)
  expect_success "relight at scale $s, direct light" gi-relight -q "$TMP/c$s.gltf" "$TMP/c$s.gip" "$TMP/c$s.gih" \
    "$TMP/v$s.script" -o "$TMP/o$s" --only direct --frames 1-6
done
val() { awk -F= -v k="$1" '$1 == k { print $2 }' "$2"; }
for s in 1000 10000; do
  for f in point-lowered camera-moved fill-light; do
    gi-compare diff "$TMP/o$s/$f.exr" "$TMP/o1/$f.exr" >"$TMP/d.txt" 2>&1
    e=$(val nrmse "$TMP/d.txt")
    check "$f at scale $s: the direct light of scale 1 within nrmse 0.01 ($e)" \
      awk -v a="$e" 'BEGIN { exit !(a != "" && a + 0 < 0.01) }'
  done
done
finish
