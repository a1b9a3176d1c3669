#!/usr/bin/env python3
"""mkfurnace.py OUT.gltf N EMISSION ALBEDO: a closed 2 x 2 x 2 m box of single-sided faces
facing in, each face cut into N x N squares (12 N^2 triangles), all of one grey material of
base colour ALBEDO that emits EMISSION nits (emissiveFactor 1 x KHR_materials_emissive_strength).
Inside it the radiance is EMISSION / (1 - ALBEDO) everywhere and in every direction: a furnace.
Its corners are concave creases between emitting faces, the case that light sampling alone
handles worst."""
import base64, json, struct, sys

def main():
    if len(sys.argv) != 5:
        sys.exit(__doc__.splitlines()[0])
    out, n, emission, albedo = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4])
    pos, idx = [], []
    # each face: origin corner, two edge vectors whose cross product points inward
    faces = [((0, 0, 0), (0, 0, 2), (2, 0, 0)),   # floor, normal +y
             ((0, 2, 0), (2, 0, 0), (0, 0, 2)),   # ceiling, -y
             ((0, 0, 0), (0, 2, 0), (0, 0, 2)),   # x = 0, +x
             ((2, 0, 0), (0, 0, 2), (0, 2, 0)),   # x = 2, -x
             ((0, 0, 0), (2, 0, 0), (0, 2, 0)),   # z = 0, +z
             ((0, 0, 2), (0, 2, 0), (2, 0, 0))]   # z = 2, -z
    for o, a, b in faces:
        base = len(pos) // 3
        for j in range(n + 1):
            for i in range(n + 1):
                pos += [o[k] + a[k] * i / n + b[k] * j / n for k in range(3)]
        for j in range(n):
            for i in range(n):
                v = base + j * (n + 1) + i
                idx += [v, v + 1, v + n + 2, v, v + n + 2, v + n + 1]
    views, accs, blob = [], [], b""
    for data, fmt, typ in ((pos, "f", "VEC3"), (idx, "I", "SCALAR")):
        raw = struct.pack("<%d%s" % (len(data), fmt), *data)
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(raw)})
        blob += raw
        a = {"bufferView": len(views) - 1, "componentType": 5126 if fmt == "f" else 5125,
             "count": len(data) // (3 if typ == "VEC3" else 1), "type": typ}
        if typ == "VEC3":
            a["min"] = [min(pos[k::3]) for k in range(3)]
            a["max"] = [max(pos[k::3]) for k in range(3)]
        accs.append(a)
    mat = {"name": "furnace", "pbrMetallicRoughness": {"baseColorFactor": [albedo, albedo, albedo, 1],
                                                       "metallicFactor": 0, "roughnessFactor": 1},
           "emissiveFactor": [1, 1, 1], "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": emission}}}
    g = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
         "extensionsUsed": ["KHR_materials_emissive_strength"],
         "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 0}]}],
         "materials": [mat],
         "buffers": [{"byteLength": len(blob), "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()}],
         "bufferViews": views, "accessors": accs}
    with open(out, "w") as f:
        f.write(json.dumps(g))

main()
