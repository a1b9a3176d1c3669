#!/usr/bin/env python3
"""mkoffice.py OUT.gltf: the office of t144, a scene no default was tuned on (written
2026-12-08). A 6 x 2.8 x 5 m room with a 2 x 1.4 m window opening (no glass) in the wall at
z = 0, whose 0.2 m reveal lets a sun in; a desk with a box on it, a shelf unit, a column, a
steel cabinet (metallic, roughness 0.5), an oak floor, sage and terracotta walls. Faces are
single-sided, facing the room; the walls, roof and floor are closed from outside by a shell
0.2 m away facing out, so that only the window admits the sun. Materials: white, oak, sage,
terracotta, desk, boxblue, steel."""
import base64, json, struct, sys

quads = []  # (corners, normal, material)

def box(lo, hi, inward, mat, skip=()):
    x0, y0, z0 = lo; x1, y1, z1 = hi
    s = 1 if inward else -1
    faces = [([(x0, y0, z0), (x1, y0, z0), (x1, y0, z1), (x0, y0, z1)], (0, s, 0)),
             ([(x0, y1, z0), (x1, y1, z0), (x1, y1, z1), (x0, y1, z1)], (0, -s, 0)),
             ([(x0, y0, z0), (x0, y1, z0), (x0, y1, z1), (x0, y0, z1)], (s, 0, 0)),
             ([(x1, y0, z0), (x1, y1, z0), (x1, y1, z1), (x1, y0, z1)], (-s, 0, 0)),
             ([(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0)], (0, 0, s)),
             ([(x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)], (0, 0, -s))]
    for i, (c, n) in enumerate(faces):
        if i in skip: continue
        quads.append((c, n, mat(i) if callable(mat) else mat))

W, H, D = 6.0, 2.8, 5.0
# room: floor 0 (oak), ceiling 1 (white), x=0 wall 2 (sage), x=W 3 (white), z=0 window wall 4, z=D 5 (terracotta)
mats = {0: 1, 1: 0, 2: 2, 3: 0, 5: 3}
box((0, 0, 0), (W, H, D), True, lambda i: mats.get(i, 0), skip=(4,))
# the window wall at z = 0 with an opening x in [2, 4], y in [0.9, 2.3], 0.2 m thick (outer face at z = -0.2)
wx0, wx1, wy0, wy1, T = 2.0, 4.0, 0.9, 2.3, 0.2
for c in ([(0, 0, 0), (wx0, 0, 0), (wx0, H, 0), (0, H, 0)], [(wx1, 0, 0), (W, 0, 0), (W, H, 0), (wx1, H, 0)],
          [(wx0, 0, 0), (wx1, 0, 0), (wx1, wy0, 0), (wx0, wy0, 0)], [(wx0, wy1, 0), (wx1, wy1, 0), (wx1, H, 0), (wx0, H, 0)]):
    quads.append((c, (0, 0, 1), 0))
# reveal: sill (facing up), head (facing down), jambs
quads.append(([(wx0, wy0, -T), (wx1, wy0, -T), (wx1, wy0, 0), (wx0, wy0, 0)], (0, 1, 0), 0))
quads.append(([(wx0, wy1, -T), (wx1, wy1, -T), (wx1, wy1, 0), (wx0, wy1, 0)], (0, -1, 0), 0))
quads.append(([(wx0, wy0, -T), (wx0, wy1, -T), (wx0, wy1, 0), (wx0, wy0, 0)], (1, 0, 0), 0))
quads.append(([(wx1, wy0, -T), (wx1, wy1, -T), (wx1, wy1, 0), (wx1, wy0, 0)], (-1, 0, 0), 0))
# the outer face of the wall, facing out (so the sun's side is closed)
for c in ([(-0.2, 0, -T), (wx0, 0, -T), (wx0, H + 0.2, -T), (-0.2, H + 0.2, -T)], [(wx1, 0, -T), (W + 0.2, 0, -T), (W + 0.2, H + 0.2, -T), (wx1, H + 0.2, -T)],
          [(wx0, 0, -T), (wx1, 0, -T), (wx1, wy0, -T), (wx0, wy0, -T)], [(wx0, wy1, -T), (wx1, wy1, -T), (wx1, H + 0.2, -T), (wx0, H + 0.2, -T)]):
    quads.append((c, (0, 0, -1), 0))
# roof and outer walls (so nothing but the window lets the sun in)
box((-0.2, -0.01, -T), (W + 0.2, H + 0.2, D + 0.2), False, 0, skip=(0, 4))
# desk: top 1.6 x 0.8 at 0.74 m, 4 cm thick, on two panel legs
box((1.5, 0.70, 1.8), (3.1, 0.74, 2.6), False, 4)
box((1.55, 0.0, 1.85), (1.6, 0.70, 2.55), False, 4)
box((3.0, 0.0, 1.85), (3.05, 0.70, 2.55), False, 4)
# a box on the desk
box((2.5, 0.74, 2.0), (2.8, 0.99, 2.3), False, 5)
# shelf unit against x = W: sides and three shelves
box((5.6, 0.0, 1.0), (5.98, 2.0, 1.03), False, 0)
box((5.6, 0.0, 3.0), (5.98, 2.0, 3.03), False, 0)
for y in (0.4, 1.0, 1.6):
    box((5.6, y, 1.03), (5.98, y + 0.025, 3.0), False, 0)
# column
box((4.2, 0.0, 3.6), (4.5, H, 3.9), False, 0, skip=(0, 1))
# metal cabinet by the x = 0 wall
box((0.02, 0.0, 3.5), (0.6, 1.1, 4.6), False, 6, skip=(0,))

materials = [
    {"name": "white", "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.78, 1], "metallicFactor": 0, "roughnessFactor": 1}},
    {"name": "oak", "pbrMetallicRoughness": {"baseColorFactor": [0.45, 0.3, 0.18, 1], "metallicFactor": 0, "roughnessFactor": 0.8}},
    {"name": "sage", "pbrMetallicRoughness": {"baseColorFactor": [0.4, 0.55, 0.4, 1], "metallicFactor": 0, "roughnessFactor": 1}},
    {"name": "terracotta", "pbrMetallicRoughness": {"baseColorFactor": [0.7, 0.3, 0.2, 1], "metallicFactor": 0, "roughnessFactor": 1}},
    {"name": "desk", "pbrMetallicRoughness": {"baseColorFactor": [0.25, 0.25, 0.28, 1], "metallicFactor": 0, "roughnessFactor": 0.6}},
    {"name": "boxblue", "pbrMetallicRoughness": {"baseColorFactor": [0.1, 0.2, 0.6, 1], "metallicFactor": 0, "roughnessFactor": 1}},
    {"name": "steel", "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.8, 1], "metallicFactor": 1, "roughnessFactor": 0.5}}]

def sub(a, b): return [a[i] - b[i] for i in range(3)]
def cross(a, b): return [a[1]*b[2]-a[2]*b[1], a[2]*b[0]-a[0]*b[2], a[0]*b[1]-a[1]*b[0]]
prims, views, accs = [], [], []
blob = b""
for mat in range(len(materials)):
    pos, idx = [], []
    for c, n, m in quads:
        if m != mat: continue
        if sum(cross(sub(c[1], c[0]), sub(c[2], c[0]))[k] * n[k] for k in range(3)) < 0:
            c = [c[0], c[3], c[2], c[1]]
        b = len(pos) // 3
        for p in c: pos += list(p)
        idx += [b, b + 1, b + 2, b, b + 2, b + 3]
    attrs = {}
    for data, fmt, typ, name in ((pos, "f", "VEC3", "POSITION"), (idx, "I", "SCALAR", None)):
        raw = struct.pack("<%d%s" % (len(data), fmt), *data)
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(raw)})
        blob += raw
        a = {"bufferView": len(views) - 1, "componentType": 5126 if fmt == "f" else 5125,
             "count": len(data) // (3 if typ == "VEC3" else 1), "type": typ}
        if name == "POSITION":
            a["min"] = [min(pos[k::3]) for k in range(3)]; a["max"] = [max(pos[k::3]) for k in range(3)]
        accs.append(a)
        if name: attrs[name] = len(accs) - 1
    prims.append({"attributes": attrs, "indices": len(accs) - 1, "material": mat})
g = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
     "meshes": [{"primitives": prims}], "materials": materials,
     "buffers": [{"byteLength": len(blob), "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()}],
     "bufferViews": views, "accessors": accs}
open(sys.argv[1], "w").write(json.dumps(g))
