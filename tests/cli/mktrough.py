#!/usr/bin/env python3
"""mktrough.py OUT.gltf: a trough (the lower half of a cylinder of radius 1 m along z, its
axis at y = 1, 4 m long, in 48 flat facets, open side up) with a board standing across it at
z = 0 (x from -1 to 1, y from 0 to 1, facing -z). A sun along +z throws the board's shadow
across the facets: a shadow's edge on a concave curved face, as on Sponza's arches seen from
below. All surfaces are one white diffuse material."""
import math, os, sys
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from gltfquads import write_quads

if len(sys.argv) != 2:
    sys.exit(__doc__.splitlines()[0])
n, z0, z1 = 48, -2.0, 2.0
quads = []
for i in range(n):
    a0 = math.pi * (i / n - 0.5)
    a1 = math.pi * ((i + 1) / n - 0.5)
    p0 = (math.sin(a0), 1 - math.cos(a0))
    p1 = (math.sin(a1), 1 - math.cos(a1))
    # the inside faces up and in (towards the axis): counter-clockwise seen from there
    quads.append([(p0[0], p0[1], z1), (p1[0], p1[1], z1), (p1[0], p1[1], z0), (p0[0], p0[1], z0)])
quads.append([(1, 0, 0), (-1, 0, 0), (-1, 1, 0), (1, 1, 0)])   # board, facing -z
quads.append([(-1, 0, 0), (1, 0, 0), (1, 1, 0), (-1, 1, 0)])   # its back, facing +z
write_quads(sys.argv[1], quads)
