"""The meshes of the soak (split from driver.py, which imports them): spot from tests/data in
every upload format (OBJ, gzipped OBJ, STL and PLY in ASCII and binary), Box.gltf and Fox.glb,
and, when ../shared/meshes is there, its larger meshes for the heavy jobs (2CylinderEngine
converted to GLB)."""
import gzip
import json
import os
import struct


def read_obj(path):
    """Vertices and triangles of an OBJ (fan-triangulated), enough to re-encode spot."""
    vs, tris = [], []
    with open(path, encoding="utf-8", errors="replace") as f:
        for line in f:
            if line.startswith("v "):
                p = line.split()
                vs.append((float(p[1]), float(p[2]), float(p[3])))
            elif line.startswith("f "):
                idx = [int(t.split("/")[0]) for t in line.split()[1:]]
                idx = [i - 1 if i > 0 else len(vs) + i for i in idx]
                for k in range(1, len(idx) - 1):
                    tris.append((idx[0], idx[k], idx[k + 1]))
    return vs, tris


def stl_binary(vs, tris):
    out = [b"voxd soak".ljust(80, b" "), struct.pack("<I", len(tris))]
    for a, b, c in tris:
        out.append(struct.pack("<12fH", 0, 0, 0, *vs[a], *vs[b], *vs[c], 0))
    return b"".join(out)


def stl_ascii(vs, tris):
    out = ["solid soak"]
    for t in tris:
        out.append(" facet normal 0 0 0\n  outer loop")
        for i in t:
            out.append("   vertex %r %r %r" % vs[i])
        out.append("  endloop\n endfacet")
    out.append("endsolid soak\n")
    return "\n".join(out).encode()


def ply_ascii(vs, tris):
    head = (
        f"ply\nformat ascii 1.0\ncomment voxd soak\nelement vertex {len(vs)}\n"
        "property float x\nproperty float y\nproperty float z\n"
        f"element face {len(tris)}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    body = "".join("%r %r %r\n" % v for v in vs) + "".join("3 %d %d %d\n" % t for t in tris)
    return (head + body).encode()


def ply_binary(vs, tris):
    head = (
        f"ply\nformat binary_little_endian 1.0\nelement vertex {len(vs)}\n"
        "property float x\nproperty float y\nproperty float z\n"
        f"element face {len(tris)}\nproperty list uchar int vertex_indices\nend_header\n"
    ).encode()
    body = b"".join(struct.pack("<3f", *v) for v in vs)
    body += b"".join(struct.pack("<B3i", 3, *t) for t in tris)
    return head + body


def gltf_to_glb(gltf_path):
    """A .gltf with one external .bin buffer as a self-contained GLB."""
    with open(gltf_path, "rb") as f:
        doc = json.load(f)
    assert len(doc["buffers"]) == 1
    with open(os.path.join(os.path.dirname(gltf_path), doc["buffers"][0]["uri"]), "rb") as f:
        binary = f.read()
    del doc["buffers"][0]["uri"]
    doc["buffers"][0]["byteLength"] = len(binary)
    js = json.dumps(doc, separators=(",", ":")).encode()
    js += b" " * (-len(js) % 4)
    binary += b"\0" * (-len(binary) % 4)
    total = 12 + 8 + len(js) + 8 + len(binary)
    return (
        struct.pack("<4sII", b"glTF", 2, total)
        + struct.pack("<I4s", len(js), b"JSON")
        + js
        + struct.pack("<I4s", len(binary), b"BIN\0")
        + binary
    )


class Mesh:
    def __init__(self, name, data, ctype, gzip_enc=False, fmt=None, aligned=False):
        self.name, self.data, self.ctype = name, data, ctype
        self.gzip_enc, self.fmt, self.aligned = gzip_enc, fmt, aligned


def load_meshes(repo, shared):
    td = os.path.join(repo, "tests", "data")

    def rd(p):
        with open(p, "rb") as f:
            return f.read()

    spot = rd(os.path.join(td, "spot.obj"))
    vs, tris = read_obj(os.path.join(td, "spot.obj"))
    small = [
        Mesh("spot.obj", spot, "model/obj", aligned=True),
        Mesh("spot.obj.gz (Content-Encoding gzip)", gzip.compress(spot), "model/obj", gzip_enc=True, aligned=True),
        Mesh("spot.stl (binary)", stl_binary(vs, tris), "model/stl", aligned=True),
        Mesh("spot.stl (ascii, sniffed)", stl_ascii(vs, tris), None, aligned=True),
        Mesh("spot.ply (ascii)", ply_ascii(vs, tris), "model/ply", aligned=True),
        Mesh("spot.ply (binary, ?format=ply)", ply_binary(vs, tris), "application/octet-stream", fmt="ply", aligned=True),
        Mesh("Box.gltf", rd(os.path.join(td, "Box.gltf")), "model/gltf+json", aligned=True),
        Mesh("Fox.glb", rd(os.path.join(td, "Fox.glb")), "model/gltf-binary"),
    ]
    heavy = []
    have_shared = shared and os.path.isfile(os.path.join(shared, "teapot.obj"))
    if have_shared:
        for n in ("suzanne.obj", "rocker-arm.obj", "teapot.obj", "stanford-bunny.obj"):
            small.append(Mesh(n, rd(os.path.join(shared, n)), "model/obj"))
        engine_glb = gltf_to_glb(os.path.join(shared, "2CylinderEngine.gltf"))
        heavy = [
            ("2CylinderEngine.glb r128 winding", Mesh("2CylinderEngine.glb", engine_glb, "model/gltf-binary"), "resolution=128&fill=winding"),
            ("teapot r256 winding", Mesh("teapot.obj", rd(os.path.join(shared, "teapot.obj")), "model/obj"), "resolution=256&fill=winding"),
            ("stanford-bunny r256 winding", Mesh("stanford-bunny.obj", rd(os.path.join(shared, "stanford-bunny.obj")), "model/obj"), "resolution=256&fill=winding"),
            ("igea-subdiv4.obj.gz r256 (1.07 M triangles)", Mesh("igea-subdiv4.obj.gz", rd(os.path.join(shared, "igea-subdiv4.obj.gz")), "model/obj", gzip_enc=True), "resolution=256&cubic=true"),
            ("igea.obj r256 conservative", Mesh("igea.obj", rd(os.path.join(shared, "igea.obj")), "model/obj"), "resolution=256&method=conservative"),
            ("2CylinderEngine.glb r256 winding", Mesh("2CylinderEngine.glb", engine_glb, "model/gltf-binary"), "resolution=256&fill=winding"),
        ]
    else:
        heavy = [
            ("spot r256 winding", small[0], "resolution=256&fill=winding"),
            ("spot r256 density x4", small[0], "resolution=256&method=density&density_factor=4"),
            ("Fox r256 winding", small[-1], "resolution=256&fill=winding"),
        ]
    return small, heavy, have_shared
