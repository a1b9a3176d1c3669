#!/usr/bin/env python3
"""mkprisms.py OUT.gltf: five columns on a floor (y = 0, 8 x 8 m), each a prism of 24 flat
sides, 0.3 m in radius and 2 m tall, in a row along z at x = 0, 1 m apart. Neighbouring
sides are 15 degrees apart: a crease under the relight's threshold (18 degrees), so where
a low sun's terminator runs down a column nothing but the light marks it. One white diffuse
material."""
import math, os, sys
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from gltfquads import write_quads

if len(sys.argv) != 2:
    sys.exit(__doc__.splitlines()[0])
N, R, H = 24, 0.3, 2.0
quads = [[(-4, 0, -4), (-4, 0, 4), (4, 0, 4), (4, 0, -4)]]  # floor, +y
for c in range(5):
    z0 = c - 2.0
    for k in range(N):
        a0, a1 = 2 * math.pi * k / N, 2 * math.pi * (k + 1) / N
        p0 = (R * math.cos(a0), R * math.sin(a0) + z0)
        p1 = (R * math.cos(a1), R * math.sin(a1) + z0)
        # outward face: counter-clockwise seen from outside
        quads.append([(p0[0], 0, p0[1]), (p0[0], H, p0[1]), (p1[0], H, p1[1]), (p1[0], 0, p1[1])])
write_quads(sys.argv[1], quads)
