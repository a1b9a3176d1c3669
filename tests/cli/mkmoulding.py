#!/usr/bin/env python3
"""mkmoulding.py OUT.gltf: a wall (z = 0, facing +z, 4 m wide, 0 <= y <= 3 m) with three
horizontal mouldings along x at y = 0.8, 1.5 and 2.2 m: half-cylinders of radius 0.08 m
standing out of it, 24 flat strips each (7.5 degrees apart, with smooth normals). Their
texture follows the profile the way Sponza's mouldings darken their grooves: the upper
half of each profile is light stone (0.8), the lower half dark (0.15); the wall is
untextured grey. Under a sun from above, the light and the texture both fall from a
moulding's top to its underside, so a pixel that sees a moulding's upper and lower halves
is lit by where it is light-coloured: its value is not its mean light times its mean
texel."""
import base64, json, math, struct, sys, zlib

if len(sys.argv) != 2:
    sys.exit(__doc__.splitlines()[0])


def png(w, h, pix):  # 8-bit RGB, rows from the top (v = 0)
    raw = b"".join(b"\x00" + bytes(pix(x, y) for x in range(w) for _ in range(3)) for y in range(h))

    def chunk(t, d):
        return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d) & 0xffffffff)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


# v = 0 at the top of the image: v < 0.5 light (the upper half of a profile), else dark
tex = png(4, 64, lambda x, y: 204 if y < 32 else 38)

R, N, X0, X1 = 0.08, 24, -2.0, 2.0
pos, nrm, uv, widx, midx = [], [], [], [], []


def vert(p, n, t):
    pos.extend(p)
    nrm.extend(n)
    uv.extend(t)
    return len(pos) // 3 - 1


# the wall
a, b, c, d = (vert((X0, 0, 0), (0, 0, 1), (0, 0)), vert((X1, 0, 0), (0, 0, 1), (0, 0)),
              vert((X1, 3, 0), (0, 0, 1), (0, 0)), vert((X0, 3, 0), (0, 0, 1), (0, 0)))
widx += [a, b, c, a, c, d]
for yc in (0.8, 1.5, 2.2):
    # profile angle from -90 (underside, meeting the wall) to +90 degrees (top)
    ring = []
    for k in range(N + 1):
        th = math.radians(-90.0 + 180.0 * k / N)
        n = (0.0, math.sin(th), math.cos(th))
        v = 0.5 - 0.5 * math.sin(th)  # top (th = 90): v = 0, light; underside: v = 1, dark
        ring.append((vert((X0, yc + R * n[1], R * n[2]), n, (0, v)),
                     vert((X1, yc + R * n[1], R * n[2]), n, (1, v))))
    for k in range(N):
        (p0, p1), (q0, q1) = ring[k], ring[k + 1]
        midx += [p0, p1, q1, p0, q1, q0]  # counter-clockwise seen from outside

blob = b""
views, accs = [], []
for data, fmt, typ, n in ((pos, "f", "VEC3", 3), (nrm, "f", "VEC3", 3), (uv, "f", "VEC2", 2),
                          (widx, "I", "SCALAR", 1), (midx, "I", "SCALAR", 1)):
    raw = struct.pack("<%d%s" % (len(data), fmt), *data)
    views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(raw)})
    blob += raw
    acc = {"bufferView": len(views) - 1, "componentType": 5126 if fmt == "f" else 5125,
           "count": len(data) // n, "type": typ}
    if len(accs) == 0:
        acc["min"] = [min(pos[k::3]) for k in range(3)]
        acc["max"] = [max(pos[k::3]) for k in range(3)]
    accs.append(acc)
attrs = {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2}
g = {
    "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
    "meshes": [{"primitives": [{"attributes": attrs, "indices": 3, "material": 0},
                               {"attributes": attrs, "indices": 4, "material": 1}]}],
    "materials": [
        {"name": "wall", "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1],
                                                  "metallicFactor": 0, "roughnessFactor": 1}},
        {"name": "moulding", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0},
                                                      "metallicFactor": 0, "roughnessFactor": 1}}],
    "textures": [{"source": 0, "sampler": 0}],
    "samplers": [{"wrapS": 33071, "wrapT": 33071}],
    "images": [{"uri": "data:image/png;base64," + base64.b64encode(tex).decode()}],
    "buffers": [{"byteLength": len(blob),
                 "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()}],
    "bufferViews": views, "accessors": accs}
with open(sys.argv[1], "w") as f:
    f.write(json.dumps(g))
