"""Makes the textured 1M-triangle mesh of issue 34's speed target: igea-subdiv4 with texture
coordinates from a planar projection (x, z normalised to [0, 1]) and a 4096² procedural texture
(smooth colour waves plus value noise: ~1M distinct colours), written as GLB by trimesh.
With `photo` the texture is a photograph instead: scikit-image's `astronaut` (Eileen Collins,
NASA, public domain; 512² shipped in the scikit-image wheel), resized to SIZE² (Lanczos).

    python bench/colour/textured.py ../shared/meshes/igea-subdiv4.obj.gz OUT.glb [SIZE] [procedural|photo]
"""
import gzip, io, sys

import numpy as np
import trimesh
from PIL import Image

src, out = sys.argv[1], sys.argv[2]
size = int(sys.argv[3]) if len(sys.argv) > 3 else 4096
kind = sys.argv[4] if len(sys.argv) > 4 else "procedural"
if kind not in ("procedural", "photo"):
    sys.exit(f"texture {kind!r}: procedural or photo")


def procedural(size):
    rng = np.random.default_rng(34)
    y, x = np.mgrid[0:size, 0:size].astype(np.float32) / size
    noise = np.asarray(Image.fromarray((rng.random((64, 64)) * 255).astype(np.uint8)).resize((size, size), Image.BICUBIC), np.float32) / 255
    rgb = np.stack([
        0.5 + 0.35 * np.sin(9 * x + 3 * noise) * np.cos(5 * y),
        0.5 + 0.35 * np.sin(7 * y + 2 * x + 4 * noise),
        0.5 + 0.35 * np.cos(11 * (x - y) + 5 * noise),
    ], -1)
    return Image.fromarray((np.clip(rgb, 0, 1) * 255).astype(np.uint8), "RGB")


data = gzip.open(src).read() if src.endswith(".gz") else open(src, "rb").read()
m = trimesh.load(io.BytesIO(data), file_type="obj", force="mesh", process=False)
v = np.asarray(m.vertices)
lo, hi = v.min(0), v.max(0)
uv = np.stack([(v[:, 0] - lo[0]) / (hi[0] - lo[0]), (v[:, 2] - lo[2]) / (hi[2] - lo[2])], 1)
if kind == "photo":
    import skimage.data

    img = Image.fromarray(skimage.data.astronaut()).resize((size, size), Image.LANCZOS)
else:
    img = procedural(size)
mat = trimesh.visual.material.PBRMaterial(baseColorTexture=img)
m.visual = trimesh.visual.TextureVisuals(uv=uv, material=mat)
m.export(out)
print(out, len(m.faces), "triangles", size, kind, "texture")

