#!/usr/bin/env python3
"""voxd against peer voxelizers, on one grid, interleaved, with a cross-check.

Subcommands (run.sh calls `run`; the others are what `run` starts in fresh subprocesses):
  run      the benchmark: for each resolution and mesh ("cell"), every tool once per round in
           rotating order, round 0 a warm-up, then the cross-check; writes results.json,
           results.md and the per-cell logs into --out
  report   rebuild results.md from a results.json (e.g. after an interrupted run)
  prepare  load a mesh with trimesh once (the same triangles for every peer) into an .npz cache
  worker   one peer, one grid: load the .npz, build the peer's mesh, time the voxelize step only,
           write the result as a packed (X, Y, Z) boolean array on voxd's grid

Grid: voxd's `--resolution N --cubic` grid (origin = bbox min, s = longest edge / N, N³), read
from the header of a reference `voxd voxelize --method surface` .vxl; every peer gets that origin,
pitch and dims, and each result is mapped to voxel-centre semantics on it:
  voxel (i, j, k) = closed box origin + [i, i+1]×[j, j+1]×[k, k+1]·s, centre origin + (i+½, j+½, k+½)·s.
"""
import argparse
import fcntl
import gzip
import hashlib
import json
import os
import platform
import re
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
from peers_report import SOLID, cmd_plot, cmd_report, fmt_mem, report, summary_line

HERE = Path(__file__).resolve().parent
LOCK = "/tmp/voxd-bench.lock"
MESHES = {  # name -> file in ../shared/meshes
    "spot": "spot.obj",
    "stanford-bunny": "stanford-bunny.obj",
    "igea": "igea.obj",
    "igea-subdiv4": "igea-subdiv4.obj.gz",
    "2CylinderEngine": "2CylinderEngine.gltf",
    "teapot": "teapot.obj",
}


# ---------------------------------------------------------------- volumes

def read_vxl(path):
    """The reader from docs/format.md: (header, uint8 (X, Y, Z) array)."""
    import struct
    import zstandard
    b = open(path, "rb").read()
    assert b[:8] == b"\x89VXL\r\n\x1a\n", "not a .vxl file"
    _version, hlen = struct.unpack_from("<II", b, 8)
    h = json.loads(b[16:16 + hlen])
    raw = zstandard.ZstdDecompressor().decompress(b[16 + hlen:])
    X, Y, Z = h["dims"]
    words = np.frombuffer(raw, "<u8").reshape(X, Y, -1)
    return h, np.unpackbits(words.view(np.uint8), axis=2, bitorder="little")[:, :, :Z]


def save_bits(path, a):
    np.savez(path, shape=np.array(a.shape), bits=np.packbits(a.astype(bool), axis=None))


def load_bits(path):
    z = np.load(path)
    shape = tuple(int(v) for v in z["shape"])
    n = shape[0] * shape[1] * shape[2]
    return np.unpackbits(z["bits"], count=n).reshape(shape).astype(bool)


def indices_to_grid(idx, dims):
    """(n, 3) integer voxel indices -> boolean grid; indices outside the grid are counted, dropped."""
    idx = np.asarray(idx, dtype=np.int64).reshape(-1, 3)
    dims = np.asarray(dims)
    ok = np.all((idx >= 0) & (idx < dims), axis=1)
    g = np.zeros(tuple(dims), dtype=bool)
    i = idx[ok]
    g[i[:, 0], i[:, 1], i[:, 2]] = True
    return g, int((~ok).sum())


def rss_kb():
    """VmRSS and VmHWM of this process, KiB."""
    out = {}
    for line in open("/proc/self/status"):
        k, _, v = line.partition(":")
        if k in ("VmRSS", "VmHWM"):
            out[k] = int(v.split()[0])
    return out


# ---------------------------------------------------------------- prepare

def load_mesh_trimesh(path):
    """The triangles voxd reads: OBJ (all objects/groups), glTF (default scene, node transforms
    applied). Vertices merged by exact position (geometry unchanged)."""
    import trimesh
    path = Path(path)
    if path.suffix == ".gz":
        with gzip.open(path, "rb") as f:
            data = f.read()
        inner = Path(path.stem).suffix.lstrip(".")
        m = trimesh.load(trimesh.util.wrap_as_stream(data), file_type=inner, process=False)
    else:
        m = trimesh.load(str(path), process=False)
    if isinstance(m, trimesh.Scene):
        m = m.to_geometry() if hasattr(m, "to_geometry") else m.dump(concatenate=True)
    V = np.asarray(m.vertices, dtype=np.float64)
    F = np.asarray(m.faces, dtype=np.int64)
    U, inv = np.unique(V, axis=0, return_inverse=True)
    return U, inv.reshape(-1)[F]


def cmd_prepare(a):
    t0 = time.perf_counter()
    V, F = load_mesh_trimesh(a.mesh)
    load_s = time.perf_counter() - t0
    np.savez(a.out, V=V, F=F)
    lo, hi = V.min(axis=0), V.max(axis=0)
    print(json.dumps({"load_s": load_s, "triangles": int(len(F)), "vertices": int(len(V)),
                      "bbox": [lo.tolist(), hi.tolist()]}))


# ---------------------------------------------------------------- workers (one peer each)

def centres(origin, s, dims, axis_slice=None):
    """(n, 3) float64 voxel centres in C order of (X, Y, Z); axis_slice restricts x."""
    X, Y, Z = dims
    xs = origin[0] + (np.arange(X) + 0.5) * s
    if axis_slice is not None:
        xs = xs[axis_slice]
    ys = origin[1] + (np.arange(Y) + 0.5) * s
    zs = origin[2] + (np.arange(Z) + 0.5) * s
    g = np.empty((len(xs), Y, Z, 3))
    g[..., 0] = xs[:, None, None]
    g[..., 1] = ys[None, :, None]
    g[..., 2] = zs[None, None, :]
    return g.reshape(-1, 3)


def worker_trimesh(V, F, origin, s, dims):
    import trimesh
    # trimesh puts voxel centres at integer multiples of the pitch: shift the mesh so that the
    # centre of voxd's voxel (i, j, k) lands on (i, j, k)·s.
    t0 = time.perf_counter()
    m = trimesh.Trimesh(V - (origin + 0.5 * s), F, process=False)
    setup = time.perf_counter() - t0
    t0 = time.perf_counter()
    # max_iter=None: trimesh subdivides as often as the longest edge needs (the default cap of
    # 10 is not enough for the long CAD triangles of 2CylinderEngine at 512³).
    vg = m.voxelized(pitch=s, max_iter=None)
    vg.fill()  # method="holes": scipy.ndimage.binary_fill_holes of the surface shell
    dense = vg.matrix
    t = time.perf_counter() - t0
    off = np.round(np.asarray(vg.translation) / s).astype(np.int64)
    idx = np.argwhere(dense) + off
    g, outside = indices_to_grid(idx, dims)
    return g, setup, t, {"outside_grid": outside}


def worker_vtk(V, F, origin, s, dims):
    import vtk
    from vtk.util import numpy_support as ns
    t0 = time.perf_counter()
    pts = vtk.vtkPoints()
    pts.SetData(ns.numpy_to_vtk(np.ascontiguousarray(V), deep=True))
    cells = vtk.vtkCellArray()
    off = np.arange(0, 3 * len(F) + 1, 3, dtype=np.int64)
    cells.SetData(ns.numpy_to_vtkIdTypeArray(off, deep=True),
                  ns.numpy_to_vtkIdTypeArray(np.ascontiguousarray(F.reshape(-1)), deep=True))
    pd = vtk.vtkPolyData()
    pd.SetPoints(pts)
    pd.SetPolys(cells)
    setup = time.perf_counter() - t0
    X, Y, Z = dims
    t0 = time.perf_counter()
    st = vtk.vtkPolyDataToImageStencil()
    st.SetInputData(pd)
    # VTK image origin and spacing are sample (voxel centre) positions.
    st.SetOutputOrigin(*(origin + 0.5 * s))
    st.SetOutputSpacing(s, s, s)
    st.SetOutputWholeExtent(0, X - 1, 0, Y - 1, 0, Z - 1)
    img = vtk.vtkImageStencilToImage()
    img.SetInputConnection(st.GetOutputPort())
    img.SetInsideValue(1)
    img.SetOutsideValue(0)
    img.SetOutputScalarTypeToUnsignedChar()
    img.Update()
    t = time.perf_counter() - t0
    out = img.GetOutput()
    a = ns.vtk_to_numpy(out.GetPointData().GetScalars())
    g = a.reshape(Z, Y, X).transpose(2, 1, 0).astype(bool)  # VTK is x fastest
    return g, setup, t, {}


def worker_open3d(V, F, origin, s, dims):
    import open3d as o3d
    t0 = time.perf_counter()
    mesh = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(V),
                                     o3d.utility.Vector3iVector(F.astype(np.int32)))
    setup = time.perf_counter() - t0
    t0 = time.perf_counter()
    vg = o3d.geometry.VoxelGrid.create_from_triangle_mesh_within_bounds(
        mesh, s, origin, origin + np.asarray(dims) * s)
    t = time.perf_counter() - t0
    # grid_index is floor((p - min_bound) / voxel_size): voxd's index on the same origin.
    vox = vg.get_voxels()
    idx = np.array([v.grid_index for v in vox], dtype=np.int64).reshape(-1, 3)
    go = np.asarray(vg.origin)
    assert np.allclose(go, origin), (go, origin)
    g, outside = indices_to_grid(idx, dims)
    return g, setup, t, {"outside_grid": outside}


def worker_igl(V, F, origin, s, dims, chunk=16 * 2**20):
    import igl
    setup = 0.0
    X, Y, Z = dims
    t0 = time.perf_counter()
    # Queries in slabs of x (<= chunk centres) to bound memory; each call builds its own tree,
    # which is part of the cost a user pays.
    per = max(1, chunk // (Y * Z))
    g = np.empty((X, Y, Z), dtype=bool)
    calls = 0
    for x0 in range(0, X, per):
        Q = centres(origin, s, dims, slice(x0, min(X, x0 + per)))
        w = igl.fast_winding_number(V, F, Q)
        g[x0:x0 + per] = (np.abs(w) >= 0.5).reshape(-1, Y, Z)
        calls += 1
    t = time.perf_counter() - t0
    return g, setup, t, {"calls": calls}


WORKERS = {"trimesh": worker_trimesh, "vtk": worker_vtk, "open3d": worker_open3d, "igl": worker_igl}


def cmd_worker(a):
    t0 = time.perf_counter()
    z = np.load(a.mesh)
    V, F = z["V"], z["F"]
    grid = json.loads(Path(a.grid).read_text())
    origin = np.array(grid["origin"], dtype=np.float64)
    s = float(grid["voxel_size"])
    dims = tuple(int(d) for d in grid["dims"])
    load = time.perf_counter() - t0
    mod_t0 = time.perf_counter()
    import importlib
    importlib.import_module({"igl": "igl", "open3d": "open3d", "vtk": "vtk", "trimesh": "trimesh"}[a.tool])
    imp = time.perf_counter() - mod_t0
    before = rss_kb()
    g, setup, t, extra = WORKERS[a.tool](V, F, origin, s, dims)
    after = rss_kb()  # VmHWM: this process's own peak (a fork's pre-exec RSS does not count here)
    save_bits(a.out, g)
    print(json.dumps({"tool": a.tool, "voxelize_s": t, "setup_s": setup, "npz_load_s": load,
                      "import_s": imp, "set": int(g.sum()), "rss_before_kb": before.get("VmRSS"),
                      "hwm_kb": after.get("VmHWM"), **extra}))


# ---------------------------------------------------------------- running children

def mem_available_kb():
    for line in open("/proc/meminfo"):
        if line.startswith("MemAvailable:"):
            return int(line.split()[1])
    return 0


def tree_rss_kb(pid):
    """Largest VmRSS among pid and its descendants, KiB."""
    best, todo = 0, [pid]
    while todo:
        q = todo.pop()
        try:
            for line in open(f"/proc/{q}/status"):
                if line.startswith("VmRSS:"):
                    best = max(best, int(line.split()[1]))
                    break
            for t in os.listdir(f"/proc/{q}/task"):
                todo += [int(c) for c in open(f"/proc/{q}/task/{t}/children").read().split()]
        except OSError:
            pass
    return best


def run_child(cmd, timeout, mem_limit_kb, log):
    """Run cmd in a fresh process group; wall clock, peak RSS, and a watchdog that kills it past
    timeout seconds or past mem_limit_kb of RSS. The peak comes from /usr/bin/time (%M) around
    the command: the ru_maxrss this process would see counts the RSS of the forked copy of this
    (large) driver before exec, so small tools would all show the driver's size."""
    out_f = tempfile.TemporaryFile()
    err_f = tempfile.TemporaryFile()
    tfile = tempfile.NamedTemporaryFile(prefix="peers-time-", delete=False)
    tfile.close()
    wrapped = (["/usr/bin/time", "-f", "%M", "-o", tfile.name, *map(str, cmd)]
               if os.path.exists("/usr/bin/time") else list(map(str, cmd)))
    killed = {"why": None}
    t0 = time.perf_counter()
    p = subprocess.Popen(wrapped, stdout=out_f, stderr=err_f, start_new_session=True)
    done = threading.Event()

    def watch():
        while not done.wait(0.1):
            if time.perf_counter() - t0 > timeout:
                killed["why"] = "timeout"
            elif tree_rss_kb(p.pid) > mem_limit_kb:
                killed["why"] = "memory"
            if killed["why"]:
                try:
                    os.killpg(p.pid, signal.SIGKILL)
                except OSError:
                    pass
                return

    th = threading.Thread(target=watch, daemon=True)
    th.start()
    _, status, ru = os.wait4(p.pid, 0)
    wall = time.perf_counter() - t0
    done.set()
    th.join()
    p.returncode = os.waitstatus_to_exitcode(status)
    out_f.seek(0)
    err_f.seek(0)
    out = out_f.read().decode(errors="replace")
    err = err_f.read().decode(errors="replace")
    peak = ru.ru_maxrss
    try:
        txt = Path(tfile.name).read_text().split()
        if txt and txt[-1].isdigit():
            peak = int(txt[-1])
    finally:
        os.unlink(tfile.name)
    log.write(f"$ {' '.join(map(str, cmd))}\n# rc {p.returncode} wall {wall:.3f} s peak rss {peak} KiB"
              f"{' killed: ' + killed['why'] if killed['why'] else ''}\n{out}{err[-4000:]}\n")
    log.flush()
    return {"rc": p.returncode, "wall_s": wall, "maxrss_kb": peak, "killed": killed["why"],
            "stdout": out, "stderr": err}


VOXD_PHASES = re.compile(r"engine (\S+)(?: \((.*)\))?, ([0-9.]+) s \(load ([0-9.]+), diagnose ([0-9.]+), "
                         r"voxelize ([0-9.]+), write ([0-9.]+)\)")


def parse_voxd(line):
    m = VOXD_PHASES.search(line)
    if not m:
        return {}
    return {"engine": m.group(1), "adapter": m.group(2), "total_s": float(m.group(3)),
            "load_s": float(m.group(4)), "diagnose_s": float(m.group(5)),
            "voxelize_s": float(m.group(6)), "write_s": float(m.group(7))}


def uptime():
    return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()


def gpu_adapter(voxd, meshes_dir, log):
    """The adapter `voxd --engine gpu` picks, or None. (lavapipe/llvmpipe is a CPU emulation.)"""
    with tempfile.TemporaryDirectory() as d:
        r = run_child([voxd, "voxelize", str(Path(meshes_dir) / "spot.obj"), "-o", f"{d}/g.vxl",
                       "--resolution", "16", "--cubic", "--engine", "gpu"], 60, 2**40, log)
    if r["rc"] != 0:
        return None, (r["stderr"].strip().splitlines() or ["no adapter"])[-1]
    ph = parse_voxd(r["stdout"])
    return ph.get("adapter") or ph.get("engine"), None


# ---------------------------------------------------------------- cross-check

def dilate1(a):
    """26-neighbourhood dilation by one voxel (no wrap-around)."""
    from scipy import ndimage
    return ndimage.binary_dilation(a, structure=np.ones((3, 3, 3), bool))


def cross_check(results, surface, tol_frac, gross_frac=0.01):
    """results: name -> bool grid (solid tools). surface: voxd's surface volume. Compares on the
    voxels outside surface dilated by one voxel: their centres are > 1.5 voxels (Chebyshev) from
    every triangle. Reference = majority of the solid results there, after leaving out tools
    that differ from a first majority on more than gross_frac of those voxels (a fill that leaked
    must not decide between the others); ties are broken by libigl's winding number when it is
    among them, and are otherwise left undecided (counted, held against no tool)."""
    far = ~dilate1(surface)
    nfar = int(far.sum())
    names = [n for n in SOLID if n in results]
    if not names:
        return {"far_voxels": nfar}
    stack = {n: results[n][far] for n in names}

    def majority(ns):
        votes = sum(stack[n].astype(np.int32) for n in ns)
        return votes * 2 > len(ns), votes * 2 == len(ns)

    ref, _ = majority(names)
    gross = [n for n in names if int((stack[n] != ref).sum()) > gross_frac * nfar]
    core = [n for n in names if n not in gross] or names
    ref, tie = majority(core)
    undecided = np.zeros_like(ref)
    if tie.any():
        if "igl" in core:
            ref = np.where(tie, stack["igl"], ref)
        else:
            undecided = tie
    decided = ~undecided
    out = {"far_voxels": nfar, "reference": "majority of " + "+".join(core), "left_out": gross,
           "ties": int(tie.sum()), "undecided": int(undecided.sum()), "tools": {}}
    for n in names:
        diff = (stack[n] != ref) & decided
        d = int(diff.sum())
        dv = int((stack[n] != stack["voxd"]).sum()) if "voxd" in stack else None
        out["tools"][n] = {"vs_reference": d, "vs_voxd": dv,
                           "extra": int((stack[n] & ~ref & decided).sum()),
                           "missing": int((~stack[n] & ref & decided).sum()),
                           "wrong": d > max(tol_frac * nfar, 0)}
    return out


def surface_agreement(a, b):
    inter = int((a & b).sum())
    union = int((a | b).sum())
    return {"voxd_surface": int(a.sum()), "open3d": int(b.sum()), "both": inter,
            "only_voxd": int((a & ~b).sum()), "only_open3d": int((b & ~a).sum()),
            "jaccard": inter / union if union else 1.0}


# ---------------------------------------------------------------- the benchmark

def sha_file(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def prepare_mesh(name, path, cache, log):
    key = sha_file(path)[:16]
    npz = cache / f"{name}-{key}.npz"
    meta = cache / f"{name}-{key}.json"
    if not (npz.exists() and meta.exists()):
        r = run_child([sys.executable, __file__, "prepare", str(path), str(npz)], 600, 2**40, log)
        if r["rc"] != 0:
            raise SystemExit(f"prepare {name} failed:\n{r['stderr']}")
        info = json.loads(r["stdout"].strip().splitlines()[-1])
        info["maxrss_kb"] = r["maxrss_kb"]
        meta.write_text(json.dumps(info))
    return npz, json.loads(meta.read_text())


def cell(args, mesh, path, npz, res, work, log):
    """One mesh at one resolution: reference voxd runs, rounds, cross-check."""
    d = work / f"{mesh}-{res}"
    d.mkdir(parents=True, exist_ok=True)
    voxd = args.voxd
    grid_args = ["--resolution", str(res), "--cubic"]
    c = {"mesh": mesh, "resolution": res, "uptime_start": uptime(), "tools": {}, "skipped": {}}
    # Reference runs (untimed): the surface (near-surface mask, Open3D's comparison) and the grid.
    r = run_child([voxd, "voxelize", str(path), "-o", str(d / "ref-surface.vxl"), "--method", "surface",
                   "--engine", "cpu", *grid_args], args.timeout, 2**40, log)
    if r["rc"] != 0:
        c["error"] = "voxd surface failed: " + r["stderr"][-500:]
        return c
    h, surf = read_vxl(d / "ref-surface.vxl")
    surf = surf.astype(bool)
    grid = {"origin": h["origin"], "voxel_size": h["voxel_size"], "dims": h["dims"]}
    (d / "grid.json").write_text(json.dumps(grid))
    c["grid"] = grid
    m = re.search(r"(\d+) triangles", r["stderr"])
    c["voxd_triangles"] = int(m.group(1)) if m else None

    tools = ["voxd", "voxd-surface"]
    if args.gpu_adapter:
        tools.append("voxd-gpu")
    for p in args.peers:
        if p == "igl" and res > args.igl_max_res:
            c["skipped"][p] = f"not run above {args.igl_max_res}³ (--igl-max-res): {res**3 / 1e6:.0f} M winding-number queries"
            continue
        if p == "trimesh" and res > args.trimesh_max_res:
            c["skipped"][p] = f"not run above {args.trimesh_max_res}³ (--trimesh-max-res)"
            continue
        tools.append(p)

    def command(t, rnd):
        if t.startswith("voxd"):
            method = "surface" if t == "voxd-surface" else "solid"
            eng = "gpu" if t == "voxd-gpu" else "cpu"
            cmd = [voxd, "voxelize", str(path), "-o", str(d / f"{t}.vxl"), "--method", method, "--engine", eng,
                   *grid_args]
            if method == "solid":
                cmd += ["--fill", args.voxd_fill]
            return cmd
        return [sys.executable, __file__, "worker", t, str(npz), str(d / "grid.json"), str(d / f"{t}.npz")]

    runs = {t: [] for t in tools}
    dead = {}
    single = set()  # warm-up slower than --slow: one timed run only
    mem_limit = args.mem_limit_gb * 2**20 if args.mem_limit_gb else max(mem_available_kb() - 2 * 2**20, 2**20)
    c["mem_limit_kb"] = mem_limit
    for rnd in range(args.runs + 1):
        k = rnd % len(tools)
        order = tools[k:] + tools[:k]
        for t in order:
            if t in dead or (t in single and rnd > 1):
                continue
            r = run_child(command(t, rnd), args.timeout, mem_limit, log)
            rec = {"round": rnd, "wall_s": r["wall_s"], "maxrss_kb": r["maxrss_kb"]}
            if r["killed"] or r["rc"] != 0:
                why = r["killed"] or f"exit {r['rc']}: " + (r["stderr"].strip().splitlines() or [""])[-1][-300:]
                dead[t] = {"why": why, "wall_s": r["wall_s"], "round": rnd, "maxrss_kb": r["maxrss_kb"]}
                continue
            if t.startswith("voxd"):
                rec.update(parse_voxd(r["stdout"]))
                rec["time_s"] = r["wall_s"]  # voxd: the whole command
                sm = re.search(r"(\d+) voxels set", r["stdout"])
                rec["set"] = int(sm.group(1)) if sm else None
                fm = re.search(r"fill (\w+)", r["stderr"])
                if fm:
                    rec["fill"] = fm.group(1)
            else:
                info = json.loads(r["stdout"].strip().splitlines()[-1])
                rec.update(info)
                if info.get("hwm_kb"):
                    rec["maxrss_kb"] = info["hwm_kb"]  # the worker's own VmHWM
                rec["time_s"] = info["voxelize_s"]  # peers: the voxelize step only
            runs[t].append(rec)
            if rnd == 0 and r["wall_s"] > args.slow and args.runs > 1:
                single.add(t)
    c["uptime_end"] = uptime()
    for t in tools:
        timed = [x for x in runs[t] if x["round"] > 0]
        e = {"runs": runs[t]}
        if t in dead:
            e["failed"] = dead[t]
        if t in single:
            e["single_run"] = True
        if timed:
            e["median_s"] = statistics.median(x["time_s"] for x in timed)
            e["maxrss_kb"] = max(x["maxrss_kb"] for x in runs[t])
            if t.startswith("voxd"):
                e["median_voxelize_s"] = statistics.median(x.get("voxelize_s", float("nan")) for x in timed)
                e["median_load_s"] = statistics.median(x.get("load_s", float("nan")) for x in timed)
            else:
                e["median_setup_s"] = statistics.median(x["setup_s"] for x in timed)
        c["tools"][t] = e

    # Cross-check on the last result each tool wrote.
    res_grids = {}
    for t in tools:
        if t in dead and not runs[t]:
            continue
        if t.startswith("voxd"):
            f = d / f"{t}.vxl"
            if f.exists():
                hh, a = read_vxl(f)
                assert hh["dims"] == grid["dims"] and hh["origin"] == grid["origin"]
                res_grids[t] = a.astype(bool)
        else:
            f = d / f"{t}.npz"
            if f.exists():
                res_grids[t] = load_bits(f)
    solids = {("voxd" if t == "voxd" else t): g for t, g in res_grids.items() if t in SOLID}
    c["cross_check"] = cross_check(solids, surf, args.tolerance)
    if "voxd-gpu" in res_grids and "voxd" in res_grids:
        c["cross_check"]["gpu_identical_to_cpu"] = bool((res_grids["voxd-gpu"] == res_grids["voxd"]).all())
    if "voxd-surface" in res_grids:
        c["cross_check"]["surface_identical_to_reference"] = bool((res_grids["voxd-surface"] == surf).all())
    if "open3d" in res_grids:
        c["cross_check"]["open3d_vs_voxd_surface"] = surface_agreement(surf, res_grids["open3d"])
    if not args.keep:
        shutil.rmtree(d, ignore_errors=True)
    return c


def cmd_run(a):
    a.meshes = [m for m in a.meshes.split(",") if m]
    a.peers = [p for p in a.peers.split(",") if p]
    a.skip = {x for x in (a.skip or "").split(",") if x}
    res = [int(r) for r in a.resolutions.split(",")]
    for m in a.meshes:
        if m not in MESHES:
            raise SystemExit(f"unknown mesh {m}: one of {', '.join(MESHES)}")
    for p in a.peers:
        if p not in WORKERS:
            raise SystemExit(f"unknown peer {p}: one of {', '.join(WORKERS)}")
    out = Path(a.out or f"/tmp/voxd-peers-{time.strftime('%Y%m%dT%H%M%S')}")
    out.mkdir(parents=True, exist_ok=True)
    work = out / "work"
    cache = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "voxd" / "peers-meshes"
    cache.mkdir(parents=True, exist_ok=True)
    log = open(out / "log.txt", "a")
    a.voxd = str(Path(a.voxd).resolve())
    deadline = None
    if a.deadline:
        hh, mm = map(int, a.deadline.split(":"))
        now = time.gmtime()
        deadline = time.mktime((now.tm_year, now.tm_mon, now.tm_mday, hh, mm, 0, 0, 0, 0)) - time.timezone
    import importlib.metadata as md
    versions = {}
    for pkg in ["numpy", "scipy", "trimesh", "vtk", "open3d-cpu", "open3d", "libigl"]:
        try:
            versions[pkg] = md.version(pkg)
        except md.PackageNotFoundError:
            pass
    cpu = next((l.split(":", 1)[1].strip() for l in open("/proc/cpuinfo") if l.startswith("model name")), "?")
    doc = {
        "command": " ".join(["bench/peers/run.sh", *sys.argv[2:]]),
        "started_utc": time.strftime("%Y-%m-%d %H:%M:%S", time.gmtime()),
        "machine": {"cpu": cpu, "cores": os.cpu_count(), "mem_gib": round(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**30, 1),
                    "kernel": platform.release(), "python": platform.python_version()},
        "voxd": {"path": a.voxd, "version": subprocess.run([a.voxd, "--version"], capture_output=True, text=True).stdout.strip(),
                 "sha256": sha_file(a.voxd)},
        "versions": versions, "runs": a.runs, "timeout_s": a.timeout, "slow": a.slow, "voxd_fill": a.voxd_fill,
        "tolerance": a.tolerance, "uptime_start": uptime(), "meshes": {}, "cells": [],
    }
    adapter, why = gpu_adapter(a.voxd, a.meshes_dir, log)
    doc["gpu"] = {"adapter": adapter, "note": why}
    a.gpu_adapter = None
    if adapter and (not re.search(r"llvmpipe|lavapipe", adapter, re.I) or a.lavapipe):
        a.gpu_adapter = adapter
    print(f"gpu: {adapter or 'none'} ({why or ''}); {'timing voxd --engine gpu' if a.gpu_adapter else 'GPU engine not timed'}", flush=True)
    t_start = time.time()
    paths = {}
    for m in a.meshes:
        p = Path(a.meshes_dir) / MESHES[m]
        npz, info = prepare_mesh(m, p, cache, log)
        doc["meshes"][m] = info
        paths[m] = (p, npz)
    for r in res:
        for m in a.meshes:
            if f"{m}@{r}" in a.skip:
                doc["cells"].append({"mesh": m, "resolution": r, "error": "not run (--skip)"})
                continue
            if deadline and time.time() > deadline:
                doc["cells"].append({"mesh": m, "resolution": r, "error": f"not run: past --deadline {a.deadline} UTC"})
                continue
            t0 = time.time()
            with open(LOCK, "a") as lk:
                if not a.no_lock:
                    fcntl.flock(lk, fcntl.LOCK_EX)
                waited = time.time() - t0
                c = cell(a, m, paths[m][0], paths[m][1], r, work, log)
            c["lock_wait_s"] = waited
            c["cell_s"] = time.time() - t0 - waited
            doc["cells"].append(c)
            print(summary_line(c), flush=True)
            doc["uptime_end"] = uptime()
            doc["total_s"] = time.time() - t_start
            (out / "results.json").write_text(json.dumps(doc, indent=1))
            (out / "results.md").write_text(report(doc))
    doc["uptime_end"] = uptime()
    doc["total_s"] = time.time() - t_start
    doc["finished_utc"] = time.strftime("%Y-%m-%d %H:%M:%S", time.gmtime())
    (out / "results.json").write_text(json.dumps(doc, indent=1))
    (out / "results.md").write_text(report(doc))
    print(f"results: {out}/results.md, {out}/results.json ({doc['total_s']:.0f} s)")


# ---------------------------------------------------------------- memory again

def cmd_memory(a):
    """Peak RSS again, one run per tool per cell, for a results.json whose timing run recorded
    ru_maxrss floored by the driver's own size (runs before /usr/bin/time wrapped each child).
    Writes doc["memory"]["MESH@RES"][tool] = KiB back into the file; the report prefers it."""
    doc = json.loads(Path(a.results).read_text())
    tools = [t for t in a.tools.split(",") if t]
    cache = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "voxd" / "peers-meshes"
    voxd = a.voxd or doc["voxd"]["path"]
    log = open(Path(a.results).with_name("memory-log.txt"), "a")
    mem = doc.setdefault("memory", {})
    with tempfile.TemporaryDirectory() as td, open(LOCK, "a") as lk:
        if not a.no_lock:
            fcntl.flock(lk, fcntl.LOCK_EX)
        mem["_uptime_start"] = uptime()
        for c in doc["cells"]:
            if "grid" not in c:
                continue
            m, res = c["mesh"], c["resolution"]
            path = Path(a.meshes_dir) / MESHES[m]
            npz, _ = prepare_mesh(m, path, cache, log)
            d = Path(td)
            (d / "grid.json").write_text(json.dumps(c["grid"]))
            row = mem.setdefault(f"{m}@{res}", {})
            for t in tools:
                if t.startswith("voxd"):
                    cmd = [voxd, "voxelize", str(path), "-o", str(d / "x.vxl"), "--engine", "cpu",
                           "--resolution", str(res), "--cubic"]
                    cmd += ["--method", "surface"] if t == "voxd-surface" else ["--method", "solid", "--fill", doc.get("voxd_fill", "auto")]
                elif t in c["tools"] and "median_s" in c["tools"][t]:
                    cmd = [sys.executable, __file__, "worker", t, str(npz), str(d / "grid.json"), str(d / "x.npz")]
                else:
                    continue
                r = run_child(cmd, a.timeout, 2**40, log)
                if r["rc"] == 0:
                    kb = r["maxrss_kb"]
                    if not t.startswith("voxd"):
                        kb = json.loads(r["stdout"].strip().splitlines()[-1]).get("hwm_kb") or kb
                    row[t] = kb
                print(f"{m} {res}³ {t}: {fmt_mem(row[t]) if t in row else 'failed'}", flush=True)
            Path(a.results).write_text(json.dumps(doc, indent=1))
        mem["_uptime_end"] = uptime()
    Path(a.results).write_text(json.dumps(doc, indent=1))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run", help="the benchmark")
    r.add_argument("--voxd", required=True, help="voxd binary")
    r.add_argument("--meshes-dir", required=True)
    r.add_argument("--meshes", default="spot,stanford-bunny,igea,igea-subdiv4,2CylinderEngine,teapot",
                   help="comma-separated, from: " + ", ".join(MESHES))
    r.add_argument("--resolutions", default="128,256,512")
    r.add_argument("--runs", type=int, default=3, help="timed runs per tool and cell, after one warm-up")
    r.add_argument("--timeout", type=float, default=180, help="seconds per tool per run")
    r.add_argument("--peers", default="trimesh,vtk,open3d,igl")
    r.add_argument("--igl-max-res", type=int, default=256, help="libigl only up to this resolution")
    r.add_argument("--trimesh-max-res", type=int, default=4096, help="trimesh only up to this resolution")
    r.add_argument("--mem-limit-gb", type=float, default=0,
                   help="kill a tool past this RSS (default: MemAvailable at the cell's start minus 2 GiB)")
    r.add_argument("--voxd-fill", default="auto", help="voxd --fill for solid (auto: parity if watertight, else winding)")
    r.add_argument("--tolerance", type=float, default=1e-5,
                   help="a solid result differing from the reference on more than this fraction of the far voxels is flagged")
    r.add_argument("--lavapipe", action="store_true", help="also time voxd --engine gpu on lavapipe/llvmpipe")
    r.add_argument("--skip", help="cells not to run, e.g. 2CylinderEngine@512,teapot@512")
    r.add_argument("--slow", type=float, default=60,
                   help="a tool whose warm-up takes longer than this many seconds gets one timed run, not --runs")
    r.add_argument("--deadline", help="HH:MM UTC: cells not started by then are skipped")
    r.add_argument("--out", help="output folder (default /tmp/voxd-peers-TIMESTAMP)")
    r.add_argument("--no-lock", action="store_true", help=f"do not take {LOCK} (smoke tests only)")
    r.add_argument("--keep", action="store_true", help="keep the volumes of every cell")
    r.set_defaults(fn=cmd_run)
    p = sub.add_parser("prepare")
    p.add_argument("mesh")
    p.add_argument("out")
    p.set_defaults(fn=cmd_prepare)
    w = sub.add_parser("worker")
    w.add_argument("tool", choices=list(WORKERS))
    w.add_argument("mesh")
    w.add_argument("grid")
    w.add_argument("out")
    w.set_defaults(fn=cmd_worker)
    pl = sub.add_parser("plot")
    pl.add_argument("results")
    pl.add_argument("out")
    pl.set_defaults(fn=cmd_plot)
    mp = sub.add_parser("memory", help="re-measure peak RSS for a results.json (one run per tool)")
    mp.add_argument("results")
    mp.add_argument("--meshes-dir", required=True)
    mp.add_argument("--voxd")
    mp.add_argument("--tools", default="voxd,voxd-surface,vtk,open3d,igl,trimesh")
    mp.add_argument("--timeout", type=float, default=300)
    mp.add_argument("--no-lock", action="store_true")
    mp.set_defaults(fn=cmd_memory)
    rp = sub.add_parser("report")
    rp.add_argument("results")
    rp.set_defaults(fn=cmd_report)
    a = ap.parse_args()
    a.fn(a)


if __name__ == "__main__":
    main()
