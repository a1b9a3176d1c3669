#!/usr/bin/env python3
"""mkplate.py OUT.gltf [H]: a wall (x = 0, facing +x, 4 m along z, 2 m high) over a floor
(y = 0, 4 x 4 m), and a plate held (by nothing) above the floor near the wall: 1 m square
over x 0.3..1.3, z -0.5..0.5, its top at y = H (default 0.05), its underside 1 cm lower, its
four edges closed. A sun from above lights the wall, the floor and the plate's top; the floor
under the plate, in a gap of H - 0.01, is dark. The plate's top and the floor under it face
the same way, H apart (a plinth over the rail it overhangs, on Sponza's upper gallery). All
surfaces are one white diffuse material."""
import os, sys
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from gltfquads import write_quads

if len(sys.argv) not in (2, 3):
    sys.exit(__doc__.splitlines()[0])
h = float(sys.argv[2]) if len(sys.argv) == 3 else 0.05
b = h - 0.01
x0, x1, z0, z1 = 0.3, 1.3, -0.5, 0.5
write_quads(sys.argv[1], [
    [(0, 0, -2), (0, 0, 2), (4, 0, 2), (4, 0, -2)],              # floor, +y
    [(0, 0, 2), (0, 0, -2), (0, 2, -2), (0, 2, 2)],              # wall, +x
    [(x0, h, z0), (x0, h, z1), (x1, h, z1), (x1, h, z0)],        # plate top, +y
    [(x0, b, z0), (x1, b, z0), (x1, b, z1), (x0, b, z1)],        # underside, -y
    [(x0, b, z0), (x0, b, z1), (x0, h, z1), (x0, h, z0)],        # -x edge
    [(x1, b, z0), (x1, h, z0), (x1, h, z1), (x1, b, z1)],        # +x edge
    [(x0, b, z0), (x0, h, z0), (x1, h, z0), (x1, b, z0)],        # -z edge
    [(x0, b, z1), (x1, b, z1), (x1, h, z1), (x0, h, z1)]])       # +z edge
