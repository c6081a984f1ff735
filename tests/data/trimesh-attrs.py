# Makes trimesh-attrs.glb: a unit box (12 triangles, watertight) as trimesh 5.2 writes it, with two
# application-specific vertex attributes, which trimesh names `_s` and `_t` (glTF 2.0 allows
# attribute names starting with `_`). Run: python3 -m venv v && v/bin/pip install trimesh==5.2.0
# numpy && v/bin/python tests/data/trimesh-attrs.py (from the repository root).
import numpy as np
import trimesh

m = trimesh.creation.box(extents=(1, 1, 1))
n = len(m.vertices)
m.vertex_attributes["s"] = np.linspace(0, 1, n).astype(np.float32)
m.vertex_attributes["t"] = np.linspace(1, 0, n).astype(np.float32)
with open("tests/data/trimesh-attrs.glb", "wb") as f:
    f.write(m.export(file_type="glb"))
