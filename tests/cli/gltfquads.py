"""gltfquads.py: write_quads(path, quads), the glTF of the test scenes made of quads (mkslit.py, mkstairs.py,
mkledge.py, mkcolumns.py, mkfins.py, mkprisms.py, mkplate.py): one mesh of one white diffuse material, each quad's
corners counter-clockwise seen from the side it faces (no normals: flat faces); box_quads, the
five faces of a box standing on the floor."""
import base64, json, struct


def box_quads(x0, z0, x1, z1, h):
    """The four sides and the top of a box standing on y = 0 over [x0, x1] x [z0, z1], h tall
    (no bottom face: the floor runs on under it)."""
    return [[(x0, 0, z0), (x0, 0, z1), (x0, h, z1), (x0, h, z0)],  # -x
            [(x1, 0, z0), (x1, h, z0), (x1, h, z1), (x1, 0, z1)],  # +x
            [(x0, 0, z0), (x0, h, z0), (x1, h, z0), (x1, 0, z0)],  # -z
            [(x0, 0, z1), (x1, 0, z1), (x1, h, z1), (x0, h, z1)],  # +z
            [(x0, h, z0), (x0, h, z1), (x1, h, z1), (x1, h, z0)]]  # top, +y


def write_quads(path, quads):
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
    with open(path, "w") as f:
        f.write(json.dumps(g))
