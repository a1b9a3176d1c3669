#!/usr/bin/env python3
"""mkcolumns.py OUT.gltf: an open court (a 10 x 10 m floor at y = 0 facing up, four 4 m walls
facing in, no roof) with five 1.2 x 1.2 x 3 m columns standing on the floor. The floor runs on
under the columns, which have no bottom face: 7.2 m2 of floor inside other geometry, as under
Sponza's columns. All surfaces are one white diffuse material."""
import os, sys
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from gltfquads import box_quads, write_quads

if len(sys.argv) != 2:
    sys.exit(__doc__.splitlines()[0])
L, H = 10, 4
quads = [[(0, 0, 0), (0, 0, L), (L, 0, L), (L, 0, 0)],  # floor, +y
         [(0, 0, 0), (L, 0, 0), (L, H, 0), (0, H, 0)],  # wall z = 0, +z
         [(0, 0, L), (0, H, L), (L, H, L), (L, 0, L)],  # wall z = L, -z
         [(0, 0, 0), (0, H, 0), (0, H, L), (0, 0, L)],  # wall x = 0, +x
         [(L, 0, 0), (L, 0, L), (L, H, L), (L, H, 0)]]  # wall x = L, -x
for x0, z0 in [(2, 2), (2, 6), (6, 2), (6, 6), (4, 4)]:
    quads += box_quads(x0, z0, x0 + 1.2, z0 + 1.2, 3)
write_quads(sys.argv[1], quads)
