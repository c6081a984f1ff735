#!/usr/bin/env python3
"""Build the triangle-count series from one watertight mesh (default: igea.obj, 268,686 triangles).

Decimated with fast-simplification (quadric edge collapse) to 10k, 30k and 100k triangles (each
checked to be a closed oriented manifold, see decimate()), the
original, and midpoint-subdivided (trimesh.remesh.subdivide: every triangle into 4, no vertex moved,
so the surface and the solid stay exactly the same) once (~1.07M) and twice (~4.3M).
Writes OBJ files into OUT_DIR as igea-<triangles>.obj, skipping ones that already exist, and
prints one line per file: path<TAB>triangles. Watertightness is checked by the caller (voxd info).
Usage: gen_meshes.py SRC.obj OUT_DIR [TARGETS (comma-separated, decimation only)]
"""
import os
import sys

import numpy as np
import trimesh
import fast_simplification


def write_obj(path, v, f):
    tmp = path + ".tmp"
    with open(tmp, "w") as fh:
        fh.write(f"# {len(f)} triangles, made by bench/scaling/gen_meshes.py\n")
        np.savetxt(fh, v, fmt="v %.9g %.9g %.9g")
        np.savetxt(fh, f + 1, fmt="f %d %d %d")
    os.replace(tmp, path)


def closed_manifold(f):
    """Every undirected edge in exactly two faces, once in each direction (closed, oriented)."""
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    d, dc = np.unique(e, axis=0, return_counts=True)
    if (dc != 1).any():
        return False
    u, uc = np.unique(np.sort(e, axis=1), axis=0, return_counts=True)
    return bool((uc == 2).all())


def decimate(v, f, target):
    """Quadric decimation to `target` faces; a collapse can pinch an edge into a non-manifold one,
    so this tries the library's aggressiveness 7 (its default), then 5, 3, 9, 6, 4, then nudged
    targets, until the result is a closed oriented manifold."""
    tries = [(7, target), (5, target), (3, target), (9, target), (6, target), (4, target)]
    tries += [(7, target + d) for d in (2, -2, 4, -4, 6, -6, 8, -8)]
    for agg, t in tries:
        vd, fd = fast_simplification.simplify(
            v.astype(np.float32), f.astype(np.int32), target_count=t, agg=agg
        )
        fd = fd.astype(np.int64)
        if closed_manifold(fd):
            print(f"# {t} triangles: aggressiveness {agg}", file=sys.stderr)
            return vd.astype(np.float64), fd
        print(f"# {t} triangles, aggressiveness {agg}: not a closed manifold", file=sys.stderr)
    raise SystemExit(f"no closed decimation near {target}")


def main():
    src, out = sys.argv[1], sys.argv[2]
    targets = [int(t) for t in (sys.argv[3] if len(sys.argv) > 3 else "10000,30000,100000").split(",")]
    os.makedirs(out, exist_ok=True)
    stem = os.path.splitext(os.path.basename(src))[0]
    mesh = trimesh.load(src, process=False, force="mesh")
    v = np.asarray(mesh.vertices, dtype=np.float64)
    f = np.asarray(mesh.faces, dtype=np.int64)
    # Merge vertices by exact position (as the meshes README does) so edges are shared.
    v, inv = np.unique(v, axis=0, return_inverse=True)
    f = inv.reshape(-1)[f]
    n0 = len(f)
    made = []
    for t in sorted(targets):
        made.append(decimate(v, f, t))
    made.append((v, f))
    vs, fs = v, f
    for _ in range(2):
        vs, fs = trimesh.remesh.subdivide(vs, fs)
        made.append((vs, fs))
    for vv, ff in made:
        path = os.path.join(out, f"{stem}-{len(ff)}.obj")
        if not os.path.exists(path):
            write_obj(path, vv, ff)
        print(f"{path}\t{len(ff)}", flush=True)
    print(f"# source {src}: {n0} triangles", file=sys.stderr)


if __name__ == "__main__":
    main()
