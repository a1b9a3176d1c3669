#!/usr/bin/env python3
"""mkledge.py OUT.gltf: a wall (x = 0, facing +x, 4 m along z, 2 m high) over a floor
(y = 0, 4 x 4 m), with a ledge along the wall: its top at y = 1 (facing up), 4 cm deep, its
front (x = 0.04) and underside (y = 0.95). A sun from above lights the ledge's top, which
throws light onto the wall just above it (a concave crease beside a lit face, as along
Sponza's mouldings). All surfaces are one white diffuse material."""
import os, sys
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from gltfquads import write_quads

if len(sys.argv) != 2:
    sys.exit(__doc__.splitlines()[0])
d, y0, y1 = 0.04, 0.95, 1.0
write_quads(sys.argv[1], [
    [(0, 0, -2), (0, 0, 2), (4, 0, 2), (4, 0, -2)],              # floor, +y
    [(0, 0, 2), (0, 0, -2), (0, 2, -2), (0, 2, 2)],              # wall, +x
    [(0, y1, 2), (d, y1, 2), (d, y1, -2), (0, y1, -2)],          # ledge top, +y
    [(d, y0, 2), (d, y0, -2), (d, y1, -2), (d, y1, 2)],          # ledge front, +x
    [(0, y0, -2), (d, y0, -2), (d, y0, 2), (0, y0, 2)]])         # ledge underside, -y
