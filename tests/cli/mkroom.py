#!/usr/bin/env python3
"""mkroom.py OUT.gltf [--metal-floor ROUGHNESS]: the closed test room of t100 and t110.

A 3 x 2.5 x 3 m room of single-sided walls facing in: white, the wall at x = 0 red; a white
block (0.7 x 0.9 x 0.7 m); a 0.6 x 0.6 m panel 5 mm under the ceiling, facing down, emitting
400 nits (emissiveFactor 1 x KHR_materials_emissive_strength 400). With --metal-floor the floor
is metal (base 0.9 0.85 0.8, metallic 1, the roughness given) and the wall at z = 3 blue.
Materials: white, red, panel, then metal and blue when used."""
import base64, json, struct, sys

def main():
    args = sys.argv[1:]
    rough = None
    if len(args) == 3 and args[1] == "--metal-floor":
        rough = float(args[2])
    elif len(args) != 1:
        sys.exit(__doc__.splitlines()[0])
    quads = []  # (corners, inward normal, material)

    def box(lo, hi, inward, mat_of_face):
        x0, y0, z0 = lo
        x1, y1, z1 = hi
        s = 1 if inward else -1
        faces = [([(x0, y0, z0), (x1, y0, z0), (x1, y0, z1), (x0, y0, z1)], (0, s, 0)),
                 ([(x0, y1, z0), (x1, y1, z0), (x1, y1, z1), (x0, y1, z1)], (0, -s, 0)),
                 ([(x0, y0, z0), (x0, y1, z0), (x0, y1, z1), (x0, y0, z1)], (s, 0, 0)),
                 ([(x1, y0, z0), (x1, y1, z0), (x1, y1, z1), (x1, y0, z1)], (-s, 0, 0)),
                 ([(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0)], (0, 0, s)),
                 ([(x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)], (0, 0, -s))]
        for i, (c, n) in enumerate(faces):
            quads.append((c, n, mat_of_face(i)))

    # faces: 0 floor, 1 ceiling, 2 x = 0, 3 x = 3, 4 z = 0, 5 z = 3
    def room_face(i):
        if i == 2:
            return 1
        if rough is not None and i == 0:
            return 3
        if rough is not None and i == 5:
            return 4
        return 0
    box((0, 0, 0), (3, 2.5, 3), True, room_face)
    box((1.6, 0, 1.2), (2.3, 0.9, 1.9), False, lambda i: 0)
    quads.append(([(1.2, 2.495, 1.2), (1.8, 2.495, 1.2), (1.8, 2.495, 1.8), (1.2, 2.495, 1.8)], (0, -1, 0), 2))

    def sub(a, b): return [a[i] - b[i] for i in range(3)]
    def cross(a, b): return [a[1]*b[2]-a[2]*b[1], a[2]*b[0]-a[0]*b[2], a[0]*b[1]-a[1]*b[0]]
    materials = [
        {"name": "white", "pbrMetallicRoughness": {"baseColorFactor": [0.7, 0.7, 0.7, 1], "metallicFactor": 0, "roughnessFactor": 1}},
        {"name": "red", "pbrMetallicRoughness": {"baseColorFactor": [0.6, 0.08, 0.06, 1], "metallicFactor": 0, "roughnessFactor": 1}},
        {"name": "panel", "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.8, 1], "metallicFactor": 0, "roughnessFactor": 1},
         "emissiveFactor": [1, 1, 1], "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 400}}}]
    if rough is not None:
        materials += [
            {"name": "metal", "pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.85, 0.8, 1], "metallicFactor": 1, "roughnessFactor": rough}},
            {"name": "blue", "pbrMetallicRoughness": {"baseColorFactor": [0.1, 0.2, 0.7, 1], "metallicFactor": 0, "roughnessFactor": 1}}]
    prims, views, accs = [], [], []
    blob = b""
    for mat in range(len(materials)):
        pos, nrm, idx = [], [], []
        for c, n, m in quads:
            if m != mat:
                continue
            if sum(cross(sub(c[1], c[0]), sub(c[2], c[0]))[k] * n[k] for k in range(3)) < 0:
                c = [c[0], c[3], c[2], c[1]]  # counter-clockwise seen from the side it faces
            b = len(pos) // 3
            for p in c:
                pos += list(p)
                nrm += list(n)
            idx += [b, b + 1, b + 2, b, b + 2, b + 3]
        attrs = {}
        for data, fmt, typ, name in ((pos, "f", "VEC3", "POSITION"), (nrm, "f", "VEC3", "NORMAL"), (idx, "H", "SCALAR", None)):
            raw = struct.pack("<%d%s" % (len(data), fmt), *data)
            while len(raw) % 4:
                raw += b"\0"
            views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(raw)})
            blob += raw
            a = {"bufferView": len(views) - 1, "componentType": 5126 if fmt == "f" else 5123,
                 "count": len(data) // (3 if typ == "VEC3" else 1), "type": typ}
            if name == "POSITION":
                a["min"] = [min(pos[k::3]) for k in range(3)]
                a["max"] = [max(pos[k::3]) for k in range(3)]
            accs.append(a)
            if name:
                attrs[name] = len(accs) - 1
        prims.append({"attributes": attrs, "indices": len(accs) - 1, "material": mat})
    g = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
         "extensionsUsed": ["KHR_materials_emissive_strength"],
         "meshes": [{"primitives": prims}], "materials": materials,
         "buffers": [{"byteLength": len(blob), "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()}],
         "bufferViews": views, "accessors": accs}
    with open(args[0], "w") as f:
        f.write(json.dumps(g))

main()
