#!/usr/bin/env python3
"""mkstairs.py OUT.gltf [STEP N Y0]: a wall (x = 0, facing +x, 4 m along z, 2 m high) over a
floor (y = 0, 4 x 4 m), with a stepped moulding along the wall: N steps of STEP metres (rise
and run; default 0.02 and 10) climbing towards the wall from Y0 (default 0.7), each a riser
facing +x and a tread facing +y, over an underside facing -y. Seen from a few metres a step is
about a pixel: the treads and risers lit by a sun from above throw light onto each other within
centimetres (Sponza's mouldings). All surfaces are one white diffuse material."""
import os, sys
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from gltfquads import write_quads

if len(sys.argv) not in (2, 5):
    sys.exit(__doc__.splitlines()[0])
s, n, y0 = (float(sys.argv[2]), int(sys.argv[3]), float(sys.argv[4])) if len(sys.argv) == 5 else (0.02, 10, 0.7)
quads = [
    [(0, 0, -2), (0, 0, 2), (4, 0, 2), (4, 0, -2)],              # floor, +y
    [(0, 0, 2), (0, 0, -2), (0, 2, -2), (0, 2, 2)],              # wall, +x
    [(0, y0, -2), (s * n, y0, -2), (s * n, y0, 2), (0, y0, 2)]]  # underside, -y
for i in range(n):
    xr, ya, yb = s * (n - i), y0 + s * i, y0 + s * (i + 1)
    quads.append([(xr, ya, 2), (xr, ya, -2), (xr, yb, -2), (xr, yb, 2)])          # riser, +x
    quads.append([(xr - s, yb, 2), (xr, yb, 2), (xr, yb, -2), (xr - s, yb, -2)])  # tread, +y
write_quads(sys.argv[1], quads)
