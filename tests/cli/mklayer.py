#!/usr/bin/env python3
"""mklayer.py OUT.gltf: a floor (y = 0, 4 x 4 m, facing up) under a ceiling (y = 2, facing
down) with a second ceiling 1 cm above it (listed first), facing down as well: a face inside other geometry
(it sees only the back of the first ceiling, which absorbs), as Sponza's vaults have. All
surfaces are one white diffuse material."""
import os, sys
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from gltfquads import write_quads

if len(sys.argv) != 2:
    sys.exit(__doc__.splitlines()[0])
write_quads(sys.argv[1], [
    [(-2, 0, -2), (-2, 0, 2), (2, 0, 2), (2, 0, -2)],             # floor, +y
    [(-2, 2.01, -2), (2, 2.01, -2), (2, 2.01, 2), (-2, 2.01, 2)],  # the layer behind the ceiling, -y
    [(-2, 2, -2), (2, 2, -2), (2, 2, 2), (-2, 2, 2)]])            # ceiling, -y
