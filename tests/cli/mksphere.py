#!/usr/bin/env python3
"""mksphere.py OUT.gltf ROUGHNESS: a smooth glossy sphere on a floor, for t115.

A UV sphere of radius 0.5 m centred at (0, 0.5, 0) (48 x 24 segments, smooth vertex normals),
metal (base 0.95 0.9 0.8, metallic 1, the roughness given), on a 6 x 6 m white floor at y = 0
(single-sided quads facing up). Materials: sphere, floor."""
import base64, json, math, struct, sys

def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__.splitlines()[0])
    rough = float(sys.argv[2])
    pos, nrm, idx = [], [], []
    nu, nv = 48, 24
    for j in range(nv + 1):
        th = math.pi * j / nv
        for i in range(nu + 1):
            ph = 2 * math.pi * i / nu
            n = (math.sin(th) * math.cos(ph), math.cos(th), math.sin(th) * math.sin(ph))
            pos.append((0.5 * n[0], 0.5 + 0.5 * n[1], 0.5 * n[2]))
            nrm.append(n)
    for j in range(nv):
        for i in range(nu):
            a, b = j * (nu + 1) + i, (j + 1) * (nu + 1) + i
            # counter-clockwise seen from outside
            if j > 0:
                idx += [a, a + 1, b]
            if j < nv - 1:
                idx += [a + 1, b + 1, b]
    nsph = len(idx)
    base = len(pos)
    for p in ((-3, 0, -3), (3, 0, -3), (3, 0, 3), (-3, 0, 3)):
        pos.append(p)
        nrm.append((0, 1, 0))
    idx += [base, base + 2, base + 1, base, base + 3, base + 2]
    blob = b"".join(struct.pack("<3f", *p) for p in pos) + b"".join(struct.pack("<3f", *n) for n in nrm)
    off_idx = len(blob)
    blob += b"".join(struct.pack("<I", i) for i in idx)
    nvtx = len(pos)
    lo = [min(p[k] for p in pos) for k in range(3)]
    hi = [max(p[k] for p in pos) for k in range(3)]
    g = {
        "asset": {"version": "2.0", "generator": "gi tests/cli/mksphere.py"},
        "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [
            {"attributes": {"POSITION": 0, "NORMAL": 1}, "indices": 2, "material": 0},
            {"attributes": {"POSITION": 0, "NORMAL": 1}, "indices": 3, "material": 1}]}],
        "materials": [
            {"name": "sphere", "pbrMetallicRoughness": {"baseColorFactor": [0.95, 0.9, 0.8, 1],
                                                        "metallicFactor": 1, "roughnessFactor": rough}},
            {"name": "floor", "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.8, 1],
                                                       "metallicFactor": 0, "roughnessFactor": 1}}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": nvtx, "type": "VEC3", "min": lo, "max": hi},
            {"bufferView": 1, "componentType": 5126, "count": nvtx, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5125, "count": nsph, "type": "SCALAR"},
            {"bufferView": 2, "byteOffset": 4 * nsph, "componentType": 5125, "count": 6, "type": "SCALAR"}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 12 * nvtx},
            {"buffer": 0, "byteOffset": 12 * nvtx, "byteLength": 12 * nvtx},
            {"buffer": 0, "byteOffset": off_idx, "byteLength": 4 * len(idx)}],
        "buffers": [{"byteLength": len(blob),
                     "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()}],
    }
    with open(sys.argv[1], "w") as f:
        json.dump(g, f)

main()
