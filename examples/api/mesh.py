"""mesh.py - libfrep from Python (the frep package of python/): compile a model,
evaluate it on numpy arrays, polygonize it and write the mesh.

    python3 mesh.py MODEL.hf OUT.stl [GRID]
"""
import sys

import numpy as np

import frep

model, out = sys.argv[1], sys.argv[2]
grid = int(sys.argv[3]) if len(sys.argv) > 3 else 64
p = frep.compile_file(model)
print("libfrep %s, %d instructions, parameters %s" % (frep.library_version(), p.size, p.params))

x = np.array([0.0, 0.5, 2.0])
print("f =", p.eval(x, np.zeros(3), np.zeros(3)))

m = p.mesh(grid=grid)
m.write(out)
print("%s: %d vertices, %d triangles" % (out, len(m.vertices), len(m.triangles)))
