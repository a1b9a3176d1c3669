#!/usr/bin/env python3
"""mkslit.py OUT.gltf GAP: a 4 x 4 m floor (y = 0, facing up) under a roof at y = 1 of two
plates (facing down) with a slit GAP metres wide between them along z at x = 0. A sun from
above throws a strip GAP wide onto the floor; seen from a few metres it is thinner than a
pixel. All surfaces are one white diffuse material."""
import base64, json, struct, sys

def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__.splitlines()[0])
    out, gap = sys.argv[1], float(sys.argv[2])
    h = gap / 2
    # quads: corners counter-clockwise seen from the side they face
    quads = [[(-2, 0, -2), (-2, 0, 2), (2, 0, 2), (2, 0, -2)],             # floor, +y
             [(-2, 1, -2), (-h, 1, -2), (-h, 1, 2), (-2, 1, 2)],           # roof, -y
             [(h, 1, -2), (2, 1, -2), (2, 1, 2), (h, 1, 2)]]
    pos, idx = [], []
    for q in quads:
        b = len(pos) // 3
        for p in q:
            pos += list(p)
        idx += [b, b + 1, b + 2, b, b + 2, b + 3]
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
    g = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
         "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 0}]}],
         "materials": [{"name": "white", "pbrMetallicRoughness": {"baseColorFactor": [0.7, 0.7, 0.7, 1],
                                                                   "metallicFactor": 0, "roughnessFactor": 1}}],
         "buffers": [{"byteLength": len(blob), "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()}],
         "bufferViews": views, "accessors": accs}
    with open(out, "w") as f:
        f.write(json.dumps(g))

main()
