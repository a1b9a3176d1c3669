#!/usr/bin/env python3
"""mkslit.py OUT.gltf GAP: a 4 x 4 m floor (y = 0, facing up) under a roof at y = 1 of two
plates (facing down) with a slit GAP metres wide between them along z at x = 0. A sun from
above throws a strip GAP wide onto the floor; seen from a few metres it is thinner than a
pixel. All surfaces are one white diffuse material."""
import os, sys
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from gltfquads import write_quads

if len(sys.argv) != 3:
    sys.exit(__doc__.splitlines()[0])
h = float(sys.argv[2]) / 2
write_quads(sys.argv[1], [
    [(-2, 0, -2), (-2, 0, 2), (2, 0, 2), (2, 0, -2)],            # floor, +y
    [(-2, 1, -2), (-h, 1, -2), (-h, 1, 2), (-2, 1, 2)],          # roof, -y
    [(h, 1, -2), (2, 1, -2), (2, 1, 2), (h, 1, 2)]])
