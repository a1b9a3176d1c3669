#!/usr/bin/env bash
# t090-relight-antialias: a floor with a fine checkerboard texture (64 x 64
# one-texel checks, repeated 16 times) seen at a grazing angle, lit by a sun
# with a wall casting a hard shadow across it: what one sample at each pixel
# centre aliases. Against a 256-spp path-traced reference at 64 x 48, the
# default relight (footprint-filtered texture, edge and shadow-edge samples)
# must be within nrmse 0.1 and well under the unfiltered one-sample image
# (--tex-filter off --aa 1). Also: each of the two halves helps on its own,
# --edge-refine improves on 3 x 3 edge samples of equal shares, and so do the
# samples' coverage shares (the default; --coverage 1: equal shares).
. "$(dirname "$0")/lib.sh"
command -v python3 >/dev/null || { echo "ok 1 # skip python3 missing"; exit 0; }
S=$TMP/floor.gltf
python3 - "$S" <<'EOF' || { not_ok "writing the textured scene"; finish; }
import base64, json, struct, sys, zlib

def png(w, h, pix):  # 8-bit RGB
    raw = b"".join(b"\x00" + bytes(pix(x, y) for x in range(w) for _ in range(3)) for y in range(h))
    def chunk(t, d):
        return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d) & 0xffffffff)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))

tex = png(64, 64, lambda x, y: 230 if (x + y) & 1 else 40)
# floor 8 x 8 m at y = 0 (uv 0..16: 16 repeats), a wall 8 m wide, 1.5 m high at z = 1, facing +z
pos = [-4, 0, -4, 4, 0, -4, 4, 0, 4, -4, 0, 4,
       -4, 0, 1, 4, 0, 1, 4, 1.5, 1, -4, 1.5, 1]
nrm = [0, 1, 0] * 4 + [0, 0, 1] * 4
uv = [0, 0, 16, 0, 16, 16, 0, 16] + [0, 0, 1, 0, 1, 1, 0, 1]
idx = [0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7]  # floor (up), then wall (towards +z)
blob = struct.pack("<%df" % len(pos), *pos) + struct.pack("<%df" % len(nrm), *nrm) + \
       struct.pack("<%df" % len(uv), *uv) + struct.pack("<%dH" % len(idx), *idx)
g = {
  "asset": {"version": "2.0"},
  "scene": 0, "scenes": [{"nodes": [0]}],
  "nodes": [{"mesh": 0}],
  "meshes": [{"primitives": [
    {"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2}, "indices": 3, "material": 0},
    {"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2}, "indices": 4, "material": 1}]}],
  "materials": [
    {"name": "checker", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0, "roughnessFactor": 1}},
    {"name": "wall", "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1], "metallicFactor": 0, "roughnessFactor": 1}}],
  "textures": [{"source": 0, "sampler": 0}],
  "samplers": [{"wrapS": 10497, "wrapT": 10497}],
  "images": [{"uri": "data:image/png;base64," + base64.b64encode(tex).decode()}],
  "buffers": [{"byteLength": len(blob), "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()}],
  "bufferViews": [
    {"buffer": 0, "byteOffset": 0, "byteLength": 96}, {"buffer": 0, "byteOffset": 96, "byteLength": 96},
    {"buffer": 0, "byteOffset": 192, "byteLength": 64}, {"buffer": 0, "byteOffset": 256, "byteLength": 12},
    {"buffer": 0, "byteOffset": 268, "byteLength": 12}],
  "accessors": [
    {"bufferView": 0, "componentType": 5126, "count": 8, "type": "VEC3", "min": [-4, 0, -4], "max": [4, 1.5, 4]},
    {"bufferView": 1, "componentType": 5126, "count": 8, "type": "VEC3"},
    {"bufferView": 2, "componentType": 5126, "count": 8, "type": "VEC2"},
    {"bufferView": 3, "componentType": 5123, "count": 6, "type": "SCALAR"},
    {"bufferView": 4, "componentType": 5123, "count": 6, "type": "SCALAR"}],
}
open(sys.argv[1], "w").write(json.dumps(g))
EOF
cat >"$TMP/v.script" <<'SCRIPT'
resolution 64 48
camera position 0.5 0.6 4.6 target -0.3 0 0 up 0 1 0 fov 50
light sun directional direction 0.35 -0.6 0.75 illuminance 1000
frame lit
SCRIPT
expect_success "precompute" gi-precompute -q "$S" -o "$TMP/f.gip" --photons 200000
expect_success "hvds" gi-hvds -q "$S" "$TMP/f.gip" -o "$TMP/f.gih"
expect_success "reference, 256 spp" gi-compare render -q "$S" "$TMP/v.script" --spp 256 -o "$TMP/ref.exr"
in=("$S" "$TMP/f.gip" "$TMP/f.gih" "$TMP/v.script")
expect_success "relight, defaults" gi-relight -q "${in[@]}" -o "$TMP/def"
expect_success "relight, one unfiltered sample per pixel" gi-relight -q "${in[@]}" -o "$TMP/raw" --tex-filter off --aa 1
expect_success "relight, texture filter only" gi-relight -q "${in[@]}" -o "$TMP/tex" --aa 1
expect_success "relight, edge samples only" gi-relight -q "${in[@]}" -o "$TMP/edge" --tex-filter off
# the sun from the camera's side: the sunlit wall's top edge against the sky
# is the contrast that --edge-refine samples more (here ~1.5x the sun's mean
# irradiance over the view, hence --refine-contrast 1)
sed 's/direction 0.35 -0.6 0.75/direction 0.35 -0.6 -0.75/' "$TMP/v.script" >"$TMP/front.script"
in2=("$S" "$TMP/f.gip" "$TMP/f.gih" "$TMP/front.script")
expect_success "reference of the front-lit frame, 256 spp" gi-compare render -q "$S" "$TMP/front.script" --spp 256 \
  -o "$TMP/ref2.exr"
expect_success "relight, 3 x 3 edge samples" gi-relight -q "${in2[@]}" -o "$TMP/aa3" --aa 3 --no-edge-refine
expect_success "relight, 3 x 3 edge samples of equal shares" gi-relight -q "${in2[@]}" -o "$TMP/aa3c1" --aa 3 \
  --coverage 1 --no-edge-refine
expect_success "relight, 3 x 3 edge samples of equal shares and --edge-refine" gi-relight -q "${in2[@]}" \
  -o "$TMP/ref3" --aa 3 --coverage 1 --edge-refine --refine-contrast 1
err() { gi-compare diff "$TMP/$1/lit.exr" "$TMP/ref.exr" 2>/dev/null | awk -F= '$1 == "nrmse" { print $2 }'; }
e_def=$(err def) e_raw=$(err raw) e_tex=$(err tex) e_edge=$(err edge)
err2() { gi-compare diff "$TMP/$1/lit.exr" "$TMP/ref2.exr" 2>/dev/null | awk -F= '$1 == "nrmse" { print $2 }'; }
e_aa3=$(err2 aa3) e_ref3=$(err2 ref3) e_aa3c1=$(err2 aa3c1)
lt() { awk -v a="$1" -v b="$2" 'BEGIN { exit !(a != "" && b != "" && a + 0 < b + 0) }'; }
check "defaults within nrmse 0.1 of the reference (nrmse $e_def)" lt "$e_def" 0.1
check "defaults under half the unfiltered one-sample error ($e_def vs $e_raw)" \
  lt "$e_def" "$(awk -v r="$e_raw" 'BEGIN { print r / 2 }')"
check "the texture filter alone helps ($e_tex < $e_raw)" lt "$e_tex" "$e_raw"
check "the edge and shadow-edge samples alone help ($e_edge < $e_raw)" lt "$e_edge" "$e_raw"
check "--edge-refine helps 3 x 3 edge samples of equal shares ($e_ref3 < $e_aa3c1)" lt "$e_ref3" "$e_aa3c1"
check "the samples' coverage shares help 3 x 3 edge samples ($e_aa3 < $e_aa3c1)" lt "$e_aa3" "$e_aa3c1"
finish
