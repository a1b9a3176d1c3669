#!/usr/bin/env python3
"""mkfins.py OUT.gltf: a 4 x 4 m floor at y = 0 (facing up) under an open sky, with eleven thin
fins standing on it: boxes 2 cm thick, 25 cm tall and 3.6 m long along z, 30 cm apart, with
their tops and sides (no bottom face). White diffuse. Cells that hold floor on both sides of a
fin are common here, as along Sponza's mouldings and column feet."""
import os, sys
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from gltfquads import box_quads, write_quads

if len(sys.argv) != 2:
    sys.exit(__doc__.splitlines()[0])
L = 4.0
quads = [[(0, 0, 0), (0, 0, L), (L, 0, L), (L, 0, 0)]]  # floor, +y
for i in range(11):
    x0 = 0.485 + 0.3 * i
    quads += box_quads(x0, 0.2, x0 + 0.02, 3.8, 0.25)
write_quads(sys.argv[1], quads)
