#!/usr/bin/env python3
"""voxd's distance fields against peers on the same grids (bench/peers/run-distance.sh runs it).

Subcommands:
  run     the benchmark: for each resolution and mesh ("cell"), voxd `--method sdf` (and
          `distance`, `surface` for their ratio), OpenVDB's level set, libigl / pysdf / Open3D
          signed distances at the band's voxel centres; the error of each against the oracle
          (oracle.py) on a random sample of band voxels, sign errors against the winding number
  report  rebuild results.md from results.json
  worker  one peer, one cell (OpenVDB's runs under /usr/bin/python3, which has pyopenvdb)
  probe   read voxd's .vdb with pyopenvdb at the sample voxels (under /usr/bin/python3)

Grid: `--resolution N --cubic --padding BAND`: origin = bbox min − BAND·s, s = longest edge / N,
(N + 2·BAND)³ voxels, so the whole band lies in the grid. Voxel (i, j, k)'s centre is
origin + (i + ½, j + ½, k + ½)·s. All tools get the same triangles: the mesh loaded once with
trimesh (peers.py prepare) and snapped to voxd's lattice (1/256 voxel, oracle.snap), in world
coordinates; voxd reads the file itself and snaps it the same way.
"""
import argparse
import fcntl
import json
import os
import re
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import oracle  # noqa: E402
import peers  # noqa: E402

MESHES = {k: peers.MESHES[k] for k in ["igea-subdiv4", "stanford-bunny", "spot", "teapot", "2CylinderEngine"]}
OPEN = {"stanford-bunny", "teapot", "2CylinderEngine"}
PEERS = ["openvdb", "igl", "pysdf", "open3d"]
SYS_PY = "/usr/bin/python3"  # Debian's python3-openvdb is built for it only
LABEL = {
    "voxd": "voxd sdf (whole command)",
    "voxd-distance": "voxd distance (whole command)",
    "voxd-surface": "voxd surface (whole command)",
    "openvdb": "OpenVDB createLevelSetFromPolygons",
    "igl": "libigl signed_distance (fast winding number)",
    "pysdf": "pysdf SDF",
    "open3d": "Open3D compute_signed_distance",
}


# ---------------------------------------------------------------- workers

def load_cell(d):
    g = json.loads((d / "grid.json").read_text())
    z = np.load(d / "mesh.npz")
    return g, z["V"], z["F"], np.load(d / "sample.npy")


def centres_of(idx, g):
    return np.asarray(g["origin"]) + (idx + 0.5) * g["voxel_size"]


def w_openvdb(d, g, V, F, S):
    import pyopenvdb as vdb
    s, o, band = g["voxel_size"], g["origin"], g["band"]
    # index (i, j, k) -> world origin + (i + ½)·s: voxd's voxel (i, j, k) is OpenVDB's (i, j, k).
    xf = vdb.createLinearTransform([[s, 0, 0, 0], [0, s, 0, 0], [0, 0, s, 0],
                                    [o[0] + s / 2, o[1] + s / 2, o[2] + s / 2, 1]])
    pts = np.ascontiguousarray(V, np.float32)
    tris = np.ascontiguousarray(F, np.int32)
    t0 = time.perf_counter()
    grid = vdb.FloatGrid.createLevelSetFromPolygons(pts, triangles=tris, transform=xf, halfWidth=float(band))
    t = time.perf_counter() - t0
    acc = grid.getConstAccessor()
    vals, act = [], []
    for i, j, k in S.tolist():
        v, a = acc.probeValue((i, j, k))
        vals.append(v)
        act.append(a)
    return t, np.array(vals, np.float64), np.array(act), {"band_voxels": int(grid.activeVoxelCount())}


def queries(d, g):
    q = np.load(d / "queries.npy")
    return centres_of(q.astype(np.int64), g)


def w_igl(d, g, V, F, S):
    import igl
    P = queries(d, g)
    Vc, Fc = np.ascontiguousarray(V), np.ascontiguousarray(F, np.int64)
    kind = igl.SIGNED_DISTANCE_TYPE_FAST_WINDING_NUMBER
    # libigl's S is (1 − 2w)·d with w its winding number (±d only where w is 0 or 1): the value
    # taken is |P − C| (C: the closest point the same call returns) with the sign of S.
    def sdist(Q):
        S_, _, C, _ = igl.signed_distance(Q, Vc, Fc, kind)
        return np.copysign(np.linalg.norm(Q - C, axis=1), S_)
    t0 = time.perf_counter()
    sd = sdist(P)
    t = time.perf_counter() - t0
    vals = sdist(centres_of(S, g))
    return t, vals, np.ones(len(S), bool), {"queries": len(P), "band_voxels": int((np.abs(sd) < g["band"] * g["voxel_size"]).sum())}


def w_pysdf(d, g, V, F, S):
    from pysdf import SDF
    P = queries(d, g).astype(np.float32)
    t0 = time.perf_counter()
    f = SDF(np.ascontiguousarray(V, np.float32), np.ascontiguousarray(F, np.uint32))
    sd = -f(P)  # pysdf: positive inside
    t = time.perf_counter() - t0
    vals = -f(centres_of(S, g).astype(np.float32)).astype(np.float64)
    return t, vals, np.ones(len(S), bool), {"queries": len(P), "band_voxels": int((np.abs(sd) < g["band"] * g["voxel_size"]).sum())}


def w_open3d(d, g, V, F, S):
    import open3d as o3d
    P = o3d.core.Tensor(queries(d, g).astype(np.float32))
    Vt = o3d.core.Tensor(np.ascontiguousarray(V, np.float32))
    Ft = o3d.core.Tensor(np.ascontiguousarray(F, np.uint32))
    t0 = time.perf_counter()
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(Vt, Ft)
    sd = scene.compute_signed_distance(P).numpy()
    t = time.perf_counter() - t0
    vals = scene.compute_signed_distance(o3d.core.Tensor(centres_of(S, g).astype(np.float32))).numpy()
    return t, vals.astype(np.float64), np.ones(len(S), bool), {"queries": int(P.shape[0]), "band_voxels": int((np.abs(sd) < g["band"] * g["voxel_size"]).sum())}


WORKERS = {"openvdb": w_openvdb, "igl": w_igl, "pysdf": w_pysdf, "open3d": w_open3d}
MODULE = {"openvdb": "pyopenvdb", "igl": "igl", "pysdf": "pysdf", "open3d": "open3d"}


def cmd_worker(a):
    d = Path(a.cell)
    g, V, F, S = load_cell(d)
    t, vals, act, extra = WORKERS[a.tool](d, g, V, F, S)
    np.save(d / f"{a.tool}-sample.npy", np.stack([vals, act.astype(np.float64)]))
    print(json.dumps({"tool": a.tool, "time_s": t, "hwm_kb": peers.rss_kb().get("VmHWM"), **extra}))


def cmd_probe(a):
    """voxd's .vdb at the sample voxels: each sample voxel's world centre taken to the file's
    index space by the file's own transform (so voxd's index convention is not assumed; the
    largest distance of such an index from an integer is reported: ~0 when centres align)."""
    import pyopenvdb as vdb
    grids = vdb.readAllGridMetadata(a.vdb)
    grid = vdb.read(a.vdb, grids[0].name)
    acc = grid.getConstAccessor()
    g = json.loads((Path(a.sample).parent / "grid.json").read_text())
    S = np.load(a.sample)
    vals, off = [], 0.0
    for c in centres_of(S, g).tolist():
        x = grid.transform.worldToIndex(tuple(c))
        ijk = tuple(int(round(v)) for v in x)
        off = max(off, max(abs(v - r) for v, r in zip(x, ijk)))
        vals.append(acc.getValue(ijk))
    np.save(a.out, np.array(vals, np.float64))
    print(json.dumps({"band_voxels": int(grid.activeVoxelCount()), "grid": grids[0].name,
                      "max_index_offset": off, "background": grid.background}))


def peer_available(tool):
    py = SYS_PY if tool == "openvdb" else sys.executable
    r = subprocess.run([py, "-c", f"import {MODULE[tool]}"], capture_output=True, text=True)
    return None if r.returncode == 0 else (r.stderr.strip().splitlines() or ["?"])[-1]


# ---------------------------------------------------------------- the benchmark

def dilate(a, k):
    """Chebyshev dilation by k voxels (separable: a cube of side 2k + 1)."""
    for ax in range(3):
        b = a.copy()
        for sh in range(1, k + 1):
            sl = [slice(None)] * 3
            sr = [slice(None)] * 3
            sl[ax], sr[ax] = slice(sh, None), slice(None, -sh)
            b[tuple(sl)] |= a[tuple(sr)]
            b[tuple(sr)] |= a[tuple(sl)]
        a = b
    return a


def voxd_record(r):
    rec = {"time_s": r["wall_s"], "maxrss_kb": r["maxrss_kb"], "rc": r["rc"], "killed": r["killed"]}
    rec.update(peers.parse_voxd(r["stdout"]))
    if r["rc"] != 0 or r["killed"]:
        rec["error"] = r["killed"] or (r["stderr"].strip().splitlines() or ["?"])[-1][-300:]
    return rec


def errors(vals, active, sample_d, wn, s, band):
    """max | |v| − d | over the sample voxels the tool holds in its band (units of s), and sign
    errors against |w| > ½ (voxels closer than 1e-6·s to the surface are not counted)."""
    ok = np.isfinite(vals) & active
    e = np.abs(np.abs(vals[ok]) - sample_d[ok] * s) / s
    inside = np.abs(wn) > 0.5
    counted = ok & (sample_d > 1e-6)
    neg = np.signbit(vals)
    return {"max_err_s": float(e.max()) if len(e) else None, "outside_band": int((~ok).sum()),
            "sign_errors": int((counted & (neg != inside)).sum()), "sign_counted": int(counted.sum())}


def cell(a, mesh, path, npz, res, work, log, big=False):
    d = work / f"{mesh}-{res}"
    d.mkdir(parents=True, exist_ok=True)
    band = a.band
    grid_args = ["--resolution", str(res), "--cubic", "--padding", str(band), "--engine", "cpu"]
    c = {"mesh": mesh, "resolution": res, "uptime_start": peers.uptime(), "tools": {}, "skipped": {}}
    t0 = time.time()
    # The grid, from the header of a surface .vxl (and the surface voxels, for the peers' queries
    # when voxd has no sdf).
    r = peers.run_child([a.voxd, "voxelize", str(path), "-o", str(d / "ref.vxl"), "--method", "surface",
                         *(grid_args if not big else ["--resolution", "64", "--cubic", "--engine", "cpu"])],
                        a.timeout, 2**40, log)
    if r["rc"] != 0:
        c["error"] = "voxd surface failed: " + r["stderr"][-300:]
        return c
    h, surf = peers.read_vxl(d / "ref.vxl")
    if big:  # the same mesh box at res: s = longest / res, origin = min − band·s
        s = h["voxel_size"] * 64 / res
        lo = np.asarray(h["origin"])
        g = {"origin": (lo - band * s).tolist(), "voxel_size": s, "dims": [res + 2 * band] * 3}
    else:
        g = {"origin": h["origin"], "voxel_size": h["voxel_size"], "dims": h["dims"]}
    g["band"] = band
    s = g["voxel_size"]
    c["grid"] = g
    # The mesh every tool gets, snapped; the oracle; the sample; the winding-number truth.
    z = np.load(npz)
    Vv = oracle.snap(z["V"], g["origin"], s)
    F = z["F"]
    np.savez(d / "mesh.npz", V=oracle.world(Vv, g["origin"], s), F=F)
    (d / "grid.json").write_text(json.dumps(g))
    orc = oracle.Oracle(Vv, F)
    S, sd = oracle.sample_band(orc, Vv, F, g["dims"], band, a.sample, seed=a.seed)
    np.save(d / "sample.npy", S)
    wn, how = oracle.winding_numbers(Vv, F, S + 0.5)
    c["sample"] = {"winding": how, "n": len(S), "inside": int((np.abs(wn) > 0.5).sum()),
                   "fragile_wn": int((np.abs(np.abs(wn) - 0.5) < 0.01).sum()), "on_surface": int((sd <= 1e-6).sum()),
                   "oracle_s": time.time() - t0}

    fmt = a.voxd_format if not big else a.big_format
    runs = {}

    def voxd_sdf(rnd):
        out = d / f"sdf.{fmt}"
        explicit = [f"--voxel-size={s!r}", "--origin=" + ",".join(map(repr, g["origin"])),
                    "--dims=" + ",".join(map(str, g["dims"])), "--engine", "cpu"]
        cmd = [a.voxd, "voxelize", str(path), "-o", str(out), "--method", "sdf", "--band", str(band),
               "--fill", "winding", *(explicit if big else grid_args)]
        return peers.run_child(cmd, a.timeout, a.mem_limit_kb, log)

    tools = ["voxd"] if a.has_sdf else []
    if not a.has_sdf:
        c["skipped"]["voxd"] = "this voxd has no --method sdf"
    if not big:
        tools += ["voxd-distance", "voxd-surface"] if res in a.distance_res and a.has_distance else []
        for p in a.peers:
            why = a.unavailable.get(p)
            if why:
                c["skipped"][p] = why
            elif p != "openvdb" and res > a.query_max_res:
                c["skipped"][p] = f"not run above {a.query_max_res}³ (--query-max-res)"
            else:
                tools.append(p)
    # voxd first (its band is the peers' query set), then the rest in rotating order.
    for rnd in range(a.runs):
        order = [t for t in tools if t != "voxd"]
        k = rnd % max(1, len(order))
        order = ["voxd"][:len(tools) - len(order)] + order[k:] + order[:k]
        for t in order:
            if t == "voxd":
                rec = voxd_record(voxd_sdf(rnd))
                if rnd == 0 and "error" not in rec:
                    prepare_queries(a, d, g, fmt, surf if not big else None, c, log)
            elif t.startswith("voxd-"):
                m = t.split("-", 1)[1]
                rec = voxd_record(peers.run_child([a.voxd, "voxelize", str(path), "-o", str(d / f"{m}.vxl"), "--method", m,
                                                   *grid_args], a.timeout, a.mem_limit_kb, log))
            else:
                if not (d / "queries.npy").exists():
                    prepare_queries(a, d, g, None, surf, c, log)
                py = SYS_PY if t == "openvdb" else sys.executable
                r = peers.run_child([py, __file__, "worker", t, str(d)], a.timeout, a.mem_limit_kb, log)
                rec = {"time_s": r["wall_s"], "maxrss_kb": r["maxrss_kb"], "rc": r["rc"]}
                if r["rc"] != 0 or r["killed"]:
                    rec["error"] = r["killed"] or (r["stderr"].strip().splitlines() or ["?"])[-1][-300:]
                else:
                    info = json.loads(r["stdout"].strip().splitlines()[-1])
                    rec.update(info)
                    rec["maxrss_kb"] = info.get("hwm_kb") or r["maxrss_kb"]
            runs.setdefault(t, []).append(rec)
    c["uptime_end"] = peers.uptime()
    for t, rs in runs.items():
        good = [x for x in rs if "error" not in x]
        e = {"runs": rs}
        if good:
            e["median_s"] = statistics.median(x["time_s"] for x in good)
            e["maxrss_kb"] = max(x["maxrss_kb"] for x in good)
            for key in ("band_voxels", "queries"):
                if key in good[-1]:
                    e[key] = good[-1][key]
        else:
            e["error"] = rs[-1].get("error")
        vals = read_values(a, d, t, fmt, g, c, log) if good else None
        if vals is not None:
            e.update(errors(vals[0], vals[1], sd, wn, s, band))
        c["tools"][t] = e
    if "band_voxels" in c:
        c["tools"].setdefault("voxd", {})["band_voxels"] = c["band_voxels"]
    c["cell_s"] = time.time() - t0
    if not a.keep:
        import shutil
        shutil.rmtree(d, ignore_errors=True)
    return c


def prepare_queries(a, d, g, fmt, surf, c, log):
    """The point peers' queries: voxd's band (|v| < band·s) when its .npy is there; else every
    voxel within `band` voxels (Chebyshev) of voxd's surface voxels (a superset of the band)."""
    band, s = g["band"], g["voxel_size"]
    if fmt == "npy" and (d / "sdf.npy").exists():
        v = np.load(d / "sdf.npy", mmap_mode="r")
        inb = np.abs(v) < np.float32(band * s)
        q = np.argwhere(inb)
        c["queries_from"] = "voxd's band"
        c["band_voxels"] = int(len(q))
    elif fmt == "vxl" and (d / "sdf.vxl").exists():
        q = sparse_band(read_sparse_vxl(d / "sdf.vxl"), band * s)
        c["queries_from"] = "voxd's band"
        c["band_voxels"] = int(len(q))
    elif surf is not None:
        q = np.argwhere(dilate(surf.astype(bool), band))
        c["queries_from"] = f"surface voxels dilated by {band} (Chebyshev; a superset of the band)"
    else:
        return
    np.save(d / "queries.npy", q.astype(np.int16 if max(g["dims"]) < 32768 else np.int32))


def read_sparse_vxl(path):
    """A `sparse-distance` .vxl (docs/format.md): header, background, tile value (None without
    tiles), brick coordinates (B, 3), brick values (B, 512), tile coordinates (T, 3)."""
    import struct
    import zstandard
    b = open(path, "rb").read()
    assert b[:8] == b"\x89VXL\r\n\x1a\n", "not a .vxl file"
    _version, hlen = struct.unpack_from("<II", b, 8)
    h = json.loads(b[16:16 + hlen])
    assert h["kind"] == "sparse-distance" and h["layout"] == "bricks8-f32le", (h["kind"], h["layout"])
    raw = zstandard.ZstdDecompressor().decompress(b[16 + hlen:])
    del b
    nb, nt = int(h["bricks"]), h.get("tiles")
    o = 0
    bg = float(np.frombuffer(raw, "<f4", 1, o)[0])
    o += 4
    tv = None
    if nt is not None:
        tv = float(np.frombuffer(raw, "<f4", 1, o)[0])
        o += 4
    coords = np.frombuffer(raw, "<u4", 3 * nb, o).reshape(nb, 3).astype(np.int64)
    o += 12 * nb
    vals = np.frombuffer(raw, "<f4", 512 * nb, o).reshape(nb, 512)
    o += 2048 * nb
    tiles = np.frombuffer(raw, "<u4", 3 * (nt or 0), o).reshape(-1, 3).astype(np.int64)
    return h, bg, tv, coords, vals, tiles


def brick_key(c):
    c = np.asarray(c, np.int64)
    return (c[:, 0] << 42) | (c[:, 1] << 21) | c[:, 2]


def sparse_at(sp, S):
    """Values of a read_sparse_vxl volume at voxels S (n, 3)."""
    _h, bg, tv, coords, vals, tiles = sp
    out = np.full(len(S), bg, np.float64)
    bk = brick_key(S // 8)
    for keys, is_tile in ((brick_key(coords), False), (brick_key(tiles), True)):
        if not len(keys):
            continue
        pos = np.minimum(np.searchsorted(keys, bk), len(keys) - 1)
        hit = keys[pos] == bk
        if is_tile:
            out[hit] = tv
        else:
            r = S % 8
            off = (r[:, 0] * 8 + r[:, 1]) * 8 + r[:, 2]
            out[hit] = vals[pos[hit], off[hit]]
    return out


def sparse_band(sp, thr):
    """Voxel indices (n, 3) of the bricks' voxels with |v| < thr."""
    _h, _bg, _tv, coords, vals, _tiles = sp
    b, off = np.nonzero(np.abs(vals) < np.float32(thr))
    return coords[b] * 8 + np.stack([off // 64, (off // 8) % 8, off % 8], axis=1)


def read_values(a, d, t, fmt, g, c, log):
    S = np.load(d / "sample.npy")
    if t == "voxd":
        f = d / f"sdf.{fmt}"
        if fmt == "npy" and f.exists():
            v = np.load(f, mmap_mode="r")
            return np.asarray(v[S[:, 0], S[:, 1], S[:, 2]], np.float64), np.abs(v[S[:, 0], S[:, 1], S[:, 2]]) < g["band"] * g["voxel_size"]
        if fmt == "vxl" and f.exists():
            v = sparse_at(read_sparse_vxl(f), S)
            return v, np.abs(v) < g["band"] * g["voxel_size"]
        if fmt == "vdb" and f.exists():
            r = peers.run_child([SYS_PY, __file__, "probe", str(f), str(d / "sample.npy"), str(d / "voxd-sample.npy")],
                                a.timeout, 2**40, log)
            if r["rc"] == 0:
                info = json.loads(r["stdout"].strip().splitlines()[-1])
                c["band_voxels"] = info["band_voxels"]
                c["vdb"] = info
                v = np.load(d / "voxd-sample.npy")
                return v, np.abs(v) < g["band"] * g["voxel_size"]
            c["voxd_read_error"] = (r["stderr"].strip().splitlines() or ["?"])[-1]
        return None
    f = d / f"{t}-sample.npy"
    if not f.exists():
        return None
    v = np.load(f)
    return v[0], v[1] > 0


def cmd_run(a):
    a.meshes = [m for m in a.meshes.split(",") if m]
    a.peers = [p for p in a.peers.split(",") if p]
    a.big_meshes = [m for m in (a.big_meshes or "").split(",") if m]
    a.distance_res = {int(r) for r in a.distance_res.split(",") if r}
    res = [int(r) for r in a.resolutions.split(",") if r]
    for m in a.meshes + a.big_meshes:
        if m not in MESHES:
            raise SystemExit(f"unknown mesh {m}: one of {', '.join(MESHES)}")
    out = Path(a.out or f"/tmp/voxd-distance-{time.strftime('%Y%m%dT%H%M%S')}")
    out.mkdir(parents=True, exist_ok=True)
    work = out / "work"
    cache = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "voxd" / "peers-meshes"
    cache.mkdir(parents=True, exist_ok=True)
    log = open(out / "log.txt", "a")
    a.voxd = str(Path(a.voxd).resolve())
    a.mem_limit_kb = a.mem_limit_gb * 2**20 if a.mem_limit_gb else max(peers.mem_available_kb() - 2 * 2**20, 2**20)
    a.unavailable = {}
    for p in a.peers:
        why = peer_available(p)
        if why:
            a.unavailable[p] = f"not installed: {why}"
            print(f"notice: {p} skipped ({why})", flush=True)
    help_txt = subprocess.run([a.voxd, "voxelize", "--help"], capture_output=True, text=True).stdout
    a.has_sdf = bool(re.search(r"\bsdf\b", help_txt))
    a.has_distance = bool(re.search(r"\bdistance\b", help_txt))
    if not a.has_sdf:
        print("notice: this voxd has no --method sdf: only the peers are measured", flush=True)
    import importlib.metadata as md
    versions = {}
    for pkg in ["numpy", "trimesh", "libigl", "open3d-cpu", "pysdf"]:
        try:
            versions[pkg] = md.version(pkg)
        except md.PackageNotFoundError:
            pass
    r = subprocess.run([SYS_PY, "-c", "import pyopenvdb as v; print('.'.join(map(str, v.LIBRARY_VERSION)))"],
                       capture_output=True, text=True)
    if r.returncode == 0:
        versions["openvdb"] = r.stdout.strip()
    cpu = next((ln.split(":", 1)[1].strip() for ln in open("/proc/cpuinfo") if ln.startswith("model name")), "?")
    doc = {"command": " ".join(["bench/peers/run-distance.sh", *sys.argv[2:]]),
           "started_utc": time.strftime("%Y-%m-%d %H:%M:%S", time.gmtime()),
           "machine": {"cpu": cpu, "cores": os.cpu_count()},
           "voxd": {"path": a.voxd, "version": subprocess.run([a.voxd, "--version"], capture_output=True, text=True).stdout.strip(),
                    "has_sdf": a.has_sdf},
           "versions": versions, "band": a.band, "sample": a.sample, "runs": a.runs,
           "skipped_peers": a.unavailable, "uptime_start": peers.uptime(), "meshes": {}, "cells": []}
    paths = {}
    for m in dict.fromkeys(a.meshes + a.big_meshes):
        p = Path(a.meshes_dir) / MESHES[m]
        npz, info = peers.prepare_mesh(m, p, cache, log)
        doc["meshes"][m] = info
        paths[m] = (p, npz)
    t_start = time.time()
    todo = [(m, r, False) for r in res for m in a.meshes] + [(m, a.big, True) for m in a.big_meshes if a.big]
    for m, r, big in todo:
        if not a.has_sdf and big:
            continue
        with open(peers.LOCK, "a") as lk:
            if not a.no_lock:
                fcntl.flock(lk, fcntl.LOCK_EX)
            c = cell(a, m, paths[m][0], paths[m][1], r, work, log, big=big)
        doc["cells"].append(c)
        print(summary_line(c), flush=True)
        doc["total_s"] = time.time() - t_start
        doc["uptime_end"] = peers.uptime()
        (out / "results.json").write_text(json.dumps(doc, indent=1))
        (out / "results.md").write_text(report(doc))
    doc["finished_utc"] = time.strftime("%Y-%m-%d %H:%M:%S", time.gmtime())
    (out / "results.json").write_text(json.dumps(doc, indent=1))
    md_txt = report(doc)
    (out / "results.md").write_text(md_txt)
    print(md_txt)
    print(f"results: {out}/results.md, {out}/results.json ({doc['total_s']:.0f} s)")


# ---------------------------------------------------------------- report

def summary_line(c):
    if "error" in c:
        return f"{c['mesh']}@{c['resolution']}: {c['error']}"
    parts = [f"{t} {e['median_s']:.3f}s" if "median_s" in e else f"{t} failed" for t, e in c["tools"].items()]
    return f"{c['mesh']}@{c['resolution']}: " + ", ".join(parts) + f" ({c.get('cell_s', 0):.0f} s)"


def fmt_mem(kb):
    return f"{kb / 2**20:.2f} GiB" if kb >= 2**20 else f"{kb / 1024:.0f} MiB"


def report(doc):
    L = [f"Distance fields: voxd against peers, band {doc['band']}, {doc['sample']} sample voxels per cell. "
         f"Started {doc['started_utc']} UTC; {doc['machine']['cpu']}, {doc['machine']['cores']} cores; "
         f"load at start: `{doc['uptime_start'].split('load average:')[-1].strip()}`, at end: "
         f"`{doc.get('uptime_end', '').split('load average:')[-1].strip()}`. voxd {doc['voxd']['version']}"
         f"{'' if doc['voxd']['has_sdf'] else ' (no --method sdf: peers only)'}; "
         + ", ".join(f"{k} {v}" for k, v in doc["versions"].items()) + ".", ""]
    for p, why in doc.get("skipped_peers", {}).items():
        L.append(f"- {p}: {why}")
    L += ["", "| mesh | grid | tool | time | time ÷ voxd sdf | peak RSS | band voxels | max \\|err\\| / s | sign errors | notes |",
          "|---|---|---|---|---|---|---|---|---|---|"]
    for c in doc["cells"]:
        n = c["resolution"] + 2 * doc["band"]
        if "error" in c:
            L.append(f"| {c['mesh']} | {c['resolution']}³ | – | – | – | – | – | – | – | {c['error']} |")
            continue
        base = c["tools"].get("voxd", {}).get("median_s")
        for t, e in c["tools"].items():
            if "median_s" not in e:
                L.append(f"| {c['mesh']} | {c['resolution']}³ | {LABEL[t]} | failed | – | – | – | – | – | {e.get('error', '')} |")
                continue
            ratio = f"{e['median_s'] / base:.2f}×" if base else "–"
            err = f"{e['max_err_s']:.2e}" if e.get("max_err_s") is not None else "–"
            sign = f"{e['sign_errors']} / {e['sign_counted']}" if "sign_errors" in e else "–"
            notes = []
            if e.get("outside_band"):
                notes.append(f"{e['outside_band']} sample voxels outside its band")
            if e.get("queries"):
                notes.append(f"{e['queries']:,} queries")
            L.append(f"| {c['mesh']} | {c['resolution']}³ ({n}³ padded) | {LABEL[t]} | {e['median_s']:.3f} s | {ratio} | "
                     f"{fmt_mem(e['maxrss_kb'])} | {e.get('band_voxels', '–'):,} | {err} | {sign} | {'; '.join(notes)} |"
                     if isinstance(e.get("band_voxels"), int) else
                     f"| {c['mesh']} | {c['resolution']}³ ({n}³ padded) | {LABEL[t]} | {e['median_s']:.3f} s | {ratio} | "
                     f"{fmt_mem(e['maxrss_kb'])} | – | {err} | {sign} | {'; '.join(notes)} |")
        for p, why in c.get("skipped", {}).items():
            if p not in doc.get("skipped_peers", {}):
                L.append(f"| {c['mesh']} | {c['resolution']}³ | {LABEL[p]} | – | – | – | – | – | – | {why} |")
    L += ["", *headline(doc)]
    L += ["", "Cells: " + "; ".join(
        f"{c['mesh']}@{c['resolution']}: sample {c.get('sample', {}).get('n')} "
        f"({c.get('sample', {}).get('inside')} inside, {c.get('sample', {}).get('fragile_wn')} with ||w|−½| < 0.01), "
        f"queries: {c.get('queries_from', '–')}" for c in doc["cells"] if "error" not in c)]
    return "\n".join(L) + "\n"


def headline(doc):
    """The issue's targets, from the cells."""
    cells = {(c["mesh"], c["resolution"]): c for c in doc["cells"] if "error" not in c}
    out = ["Targets:"]

    def med(c, t):
        return c["tools"].get(t, {}).get("median_s")

    c = cells.get(("igea-subdiv4", 512))
    if c and med(c, "voxd") and med(c, "openvdb"):
        v = c["tools"]["voxd"]
        out.append(f"- igea-subdiv4 at 512³, band 3: OpenVDB {med(c, 'openvdb'):.2f} s / voxd {med(c, 'voxd'):.2f} s = "
                   f"**{med(c, 'openvdb') / med(c, 'voxd'):.1f}×** (target ≥ 3×); voxd's max error "
                   f"{v.get('max_err_s', float('nan')):.2e}·s (target ≤ 1e-6·s), OpenVDB's "
                   f"{c['tools']['openvdb'].get('max_err_s', float('nan')):.2e}·s")
    for m in sorted(OPEN):
        for (mm, r), c in sorted(cells.items()):
            if mm != m:
                continue
            parts = [f"{t} {e['sign_errors']}/{e['sign_counted']}" for t, e in c["tools"].items() if "sign_errors" in e]
            if parts:
                out.append(f"- sign errors, {m} at {r}³ (open; voxd fill=winding): " + ", ".join(parts))
    for (m, r), c in sorted(cells.items()):
        if r > 512 and "voxd" in c["tools"] and "maxrss_kb" in c["tools"]["voxd"]:
            e = c["tools"]["voxd"]
            out.append(f"- {m} at {r}³, band 3: voxd {e['median_s']:.2f} s, peak RSS **{fmt_mem(e['maxrss_kb'])}** "
                       f"(target < 2 GB), max error {e.get('max_err_s', float('nan')):.2e}·s, "
                       f"sign errors {e.get('sign_errors', '–')}")
    for (m, r), c in sorted(cells.items()):
        if med(c, "voxd-distance") and med(c, "voxd-surface"):
            out.append(f"- {m} at {r}³: distance {med(c, 'voxd-distance'):.3f} s / surface {med(c, 'voxd-surface'):.3f} s "
                       f"= {med(c, 'voxd-distance') / med(c, 'voxd-surface'):.2f}× (target ≤ 2×)")
    return out


def cmd_report(a):
    doc = json.loads(Path(a.results).read_text())
    print(report(doc))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run")
    r.add_argument("--voxd", required=True)
    r.add_argument("--meshes-dir", required=True)
    r.add_argument("--meshes", default=",".join(MESHES))
    r.add_argument("--resolutions", default="256,512")
    r.add_argument("--big", type=int, default=2048, help="voxd alone at this resolution (0: none)")
    r.add_argument("--big-meshes", default="igea-subdiv4")
    r.add_argument("--big-format", default="vxl", help="voxd's output at --big (vxl, vdb)")
    r.add_argument("--voxd-format", default="vxl", help="voxd's sdf output at --resolutions (vxl, npy, vdb; values read back)")
    r.add_argument("--distance-res", default="512", help="grids where voxd distance and surface are timed too")
    r.add_argument("--band", type=int, default=3)
    r.add_argument("--peers", default=",".join(PEERS))
    r.add_argument("--query-max-res", type=int, default=256, help="libigl, pysdf, Open3D only up to this resolution")
    r.add_argument("--sample", type=int, default=2000)
    r.add_argument("--seed", type=int, default=20261204)
    r.add_argument("--runs", type=int, default=1)
    r.add_argument("--timeout", type=float, default=300)
    r.add_argument("--mem-limit-gb", type=float, default=0)
    r.add_argument("--out")
    r.add_argument("--keep", action="store_true")
    r.add_argument("--no-lock", action="store_true")
    rp = sub.add_parser("report")
    rp.add_argument("results")
    w = sub.add_parser("worker")
    w.add_argument("tool", choices=list(WORKERS))
    w.add_argument("cell")
    pr = sub.add_parser("probe")
    pr.add_argument("vdb")
    pr.add_argument("sample")
    pr.add_argument("out")
    a = ap.parse_args()
    {"run": cmd_run, "report": cmd_report, "worker": cmd_worker, "probe": cmd_probe}[a.cmd](a)


if __name__ == "__main__":
    main()
