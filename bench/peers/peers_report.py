"""The tables and plots of `peers.py`'s results: `report` (markdown) and `plot` (a bar chart),
and the formatting the run's summary lines share (split from peers.py, which imports them)."""
import json
import sys
from pathlib import Path


SOLID = ["voxd", "trimesh", "vtk", "igl"]  # tools whose result is a solid
LABEL = {
    "voxd": "voxd cpu solid",
    "voxd-surface": "voxd cpu surface",
    "voxd-gpu": "voxd gpu solid",
    "trimesh": "trimesh voxelized().fill()",
    "vtk": "VTK PolyDataToImageStencil",
    "igl": "libigl fast winding ≥ ½",
    "open3d": "Open3D surface",
}


def summary_line(c):
    if "error" in c:
        return f"{c['mesh']} {c['resolution']}³: {c['error']}"
    parts = []
    for t, e in c["tools"].items():
        parts.append(f"{t} {fmt_t(c, t)}")
    cc = c.get("cross_check", {})
    bad = [t for t, v in cc.get("tools", {}).items() if v["wrong"]]
    return (f"{c['mesh']} {c['resolution']}³ ({c['cell_s']:.0f} s, waited {c['lock_wait_s']:.0f} s): " + ", ".join(parts)
            + f"; differ: {','.join(bad) or 'none'}")


def fmt_s(x):
    if x is None:
        return "–"
    return f"{x:.3f} s" if x < 1 else f"{x:.2f} s" if x < 10 else f"{x:.1f} s"


def fmt_t(c, t):
    e = c["tools"].get(t)
    if e is None:
        return "skipped" if t in c.get("skipped", {}) else "–"
    if "median_s" in e:
        return fmt_s(e["median_s"]) + (" ¹" if e.get("single_run") else "")
    f = e.get("failed", {})
    if f.get("why") == "timeout":
        return f"> {f['wall_s']:.0f} s (timeout)"
    if f.get("why") == "memory":
        return f"killed: RSS > {c['mem_limit_kb'] / 2**20:.1f} GiB"
    return "failed"


def fmt_mem(kb):
    return f"{kb / 2**20:.2f} GiB" if kb >= 2**20 else f"{kb / 1024:.0f} MiB"


def wrong(c, t):
    v = c.get("cross_check", {}).get("tools", {}).get(t)
    return bool(v and v["wrong"])


def fmt_ratio(x):
    return f"{x:.1f}×" if x >= 1 else f"{x:.2f}×"


def fastest_peer(c):
    """Fastest solid peer whose result agreed with the reference; (name, time) or None."""
    best = None
    for t in ["trimesh", "vtk", "igl"]:
        e = c["tools"].get(t, {})
        if "median_s" in e and not wrong(c, t):
            if best is None or e["median_s"] < best[1]:
                best = (t, e["median_s"])
    return best


def report(doc):
    L = []
    m = doc["machine"]
    L.append(f"Command: `{doc['command']}`  ")
    L.append(f"Started {doc['started_utc']} UTC; {doc.get('total_s', 0):.0f} s in all. voxd: `{doc['voxd']['path']}` "
             f"({doc['voxd']['version']}, sha256 {doc['voxd'].get('sha256', '?')[:12]}). Machine: {m['cpu']}, {m['cores']} cores, {m['mem_gib']} GiB, "
             f"Linux {m['kernel']}, Python {m['python']}. Peers: "
             + ", ".join(f"{k} {v}" for k, v in doc["versions"].items()) + ".  ")
    L.append(f"Load at start: `{doc['uptime_start']}`; at end: `{doc.get('uptime_end', '?')}`.  ")
    g = doc["gpu"]
    L.append(f"GPU: {g['adapter'] or 'no adapter'}" + (f" ({g['note']})" if g.get("note") else "")
             + "; the GPU engine is timed only on a real adapter (not lavapipe/llvmpipe)." )
    L.append("")
    L.append(f"Times: median of {doc['runs']} runs after a warm-up, tools interleaved (every tool once per round, "
             f"rotating order), each in a fresh process. voxd = the whole `voxd voxelize` command (read, "
             f"diagnose, voxelize, write .vxl; solid with `--fill {doc['voxd_fill']}`); peers = their voxelize step "
             f"only, mesh already in memory. Peak memory = the process's peak RSS (VmHWM / GNU time %M). "
             f"Ratio = fastest solid peer that passed the cross-check / voxd solid. "
             f"Timeout {doc['timeout_s']:.0f} s per run.")
    L.append("")
    cells = doc["cells"]
    for r in sorted({c["resolution"] for c in cells}):
        L.append(f"### {r}³")
        L.append("")
        L.append("| mesh | triangles | voxd solid (engine) | trimesh fill | VTK stencil | libigl winding | "
                 "fastest solid peer / voxd | Open3D surface | voxd surface | differ |")
        L.append("|---|---|---|---|---|---|---|---|---|---|")
        for c in [c for c in cells if c["resolution"] == r]:
            if "error" in c:
                L.append(f"| {c['mesh']} | | {c['error']} | | | | | | | |")
                continue
            tri = doc["meshes"].get(c["mesh"], {}).get("triangles")
            v = c["tools"].get("voxd", {})
            vs = fmt_t(c, "voxd")
            if "median_voxelize_s" in v:
                vs += f" ({fmt_s(v['median_voxelize_s'])})"
            fill = next((x.get("fill") for x in v.get("runs", []) if x.get("fill")), None)
            if fill and fill != "parity":
                vs += f" {fill}"
            fp = fastest_peer(c)
            ratio = f"{fmt_ratio(fp[1] / v['median_s'])} ({fp[0]})" if fp and "median_s" in v else "–"
            if "median_s" in v:
                for t in ["trimesh", "vtk", "igl"]:
                    e = c["tools"].get(t, {})
                    if wrong(c, t) and "median_s" in e and (fp is None or e["median_s"] < fp[1]):
                        ratio += f"; {t} ✗ {fmt_ratio(e['median_s'] / v['median_s'])}"
            cols = []
            for t in ["trimesh", "vtk", "igl"]:
                s = fmt_t(c, t)
                if wrong(c, t):
                    s += " ✗"
                cols.append(s)
            bad = [t for t, x in c.get("cross_check", {}).get("tools", {}).items() if x["wrong"]]
            L.append(f"| {c['mesh']} | {tri or 0:,} | {vs} | {' | '.join(cols)} | {ratio} | {fmt_t(c, 'open3d')} | "
                     f"{fmt_t(c, 'voxd-surface')} | {', '.join(bad) or 'none'} |")
        L.append("")
    L.append("✗ = differs from the reference on more than "
             f"{doc['tolerance'] * 100:g} % of the voxels far from the surface (not used for the ratio); "
             "voxd solid's voxelize phase in brackets. ¹ = one timed run: its warm-up took longer than "
             f"{doc.get('slow', 60):.0f} s (--slow).")
    L.append("")
    L.append("### Peak memory (RSS)")
    L.append("")
    L.append("| mesh | grid | voxd solid | voxd surface | trimesh | VTK | libigl | Open3D |")
    L.append("|---|---|---|---|---|---|---|---|")
    for c in cells:
        if "error" in c:
            continue
        row = []
        again = doc.get("memory", {}).get(f"{c['mesh']}@{c['resolution']}", {})
        for t in ["voxd", "voxd-surface", "trimesh", "vtk", "igl", "open3d"]:
            e = c["tools"].get(t)
            if t in again:
                row.append(fmt_mem(again[t]))
            elif e and "median_s" in e:
                hw = [x.get("hwm_kb") for x in e["runs"] if x.get("hwm_kb")]
                row.append(fmt_mem(max(hw)) if hw else fmt_mem(e["maxrss_kb"]))
            else:
                row.append(fmt_t(c, t))
        L.append(f"| {c['mesh']} | {c['resolution']}³ | " + " | ".join(row) + " |")
    L.append("")
    L.append("### Cross-check (voxels whose centre is more than 1.5 voxels from the surface)")
    L.append("")
    L.append("Far voxels = outside voxd's `surface` volume dilated by one voxel (26-neighbourhood). Reference = "
             "majority of the solid results there, leaving out a result more than 1 % off a first majority (a fill "
             "that leaked); ties go to libigl's winding number, and without it stay undecided. Each entry: voxels "
             "that differ from the reference (extra / missing). Open3D (surface only) against voxd `--method surface`: "
             "Jaccard index and the voxels only one of them marks.")
    L.append("")
    L.append("| mesh | grid | far voxels | voxd | trimesh | VTK | libigl | Open3D vs voxd surface |")
    L.append("|---|---|---|---|---|---|---|---|")
    for c in cells:
        cc = c.get("cross_check")
        if not cc:
            continue
        row = []
        for t in SOLID:
            x = cc.get("tools", {}).get(t)
            row.append("–" if x is None else f"{x['vs_reference']:,} ({x['extra']:,} / {x['missing']:,})"
                       + (" ✗" if x["wrong"] else ""))
        o = cc.get("open3d_vs_voxd_surface")
        os_ = (f"{o['jaccard'] * 100:.2f} % (only voxd {o['only_voxd']:,}, only Open3D {o['only_open3d']:,})"
               if o else "–")
        und = f" ({cc['undecided']:,} undecided)" if cc.get("undecided") else ""
        L.append(f"| {c['mesh']} | {c['resolution']}³ | {cc['far_voxels']:,}{und} | " + " | ".join(row) + f" | {os_} |")
    L.append("")
    sk = [(c["mesh"], c["resolution"], t, why) for c in cells for t, why in c.get("skipped", {}).items()]
    fl = [(c["mesh"], c["resolution"], t, e["failed"]) for c in cells for t, e in c.get("tools", {}).items()
          if "failed" in e]
    if sk or fl:
        L.append("### Skipped and failed")
        L.append("")
        for mesh, r, t, why in sk:
            L.append(f"- {mesh} {r}³ {t}: {why}")
        for mesh, r, t, f in fl:
            L.append(f"- {mesh} {r}³ {t}: {f['why']} (round {f['round']}, after {f['wall_s']:.1f} s, RSS {fmt_mem(f['maxrss_kb'])})")
        L.append("")
    L.append("### Per cell: load average and wall time")
    L.append("")
    for c in cells:
        if "error" in c:
            continue
        L.append(f"- {c['mesh']} {c['resolution']}³: {c['cell_s']:.0f} s (waited {c['lock_wait_s']:.0f} s for the lock); "
                 f"start `{c['uptime_start'].split('load average:')[-1].strip()}`, end `{c['uptime_end'].split('load average:')[-1].strip()}`")
    L.append("")
    L.append("Mesh load (trimesh, once, into the peers' cache): " + ", ".join(
        f"{k} {fmt_s(v['load_s'])}" for k, v in doc["meshes"].items()) + ".")
    return "\n".join(L) + "\n"


def cmd_plot(a):
    """One panel per resolution: time per tool and mesh, log scale (✗ results hatched)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    doc = json.loads(Path(a.results).read_text())
    cells = [c for c in doc["cells"] if "tools" in c]
    resl = sorted({c["resolution"] for c in cells})
    tools = ["voxd", "trimesh", "vtk", "igl", "open3d"]
    colors = {"voxd": "#d62728", "trimesh": "#1f77b4", "vtk": "#2ca02c", "igl": "#9467bd", "open3d": "#8c8c8c"}
    fig, axes = plt.subplots(1, len(resl), figsize=(5.2 * len(resl), 4.2), squeeze=False)
    for ax, r in zip(axes[0], resl):
        cs = [c for c in cells if c["resolution"] == r]
        w = 0.8 / len(tools)
        for i, t in enumerate(tools):
            xs, ys, hatch = [], [], []
            for j, c in enumerate(cs):
                e = c["tools"].get(t, {})
                if "median_s" in e:
                    xs.append(j + (i - len(tools) / 2 + 0.5) * w)
                    ys.append(e["median_s"])
                    hatch.append(wrong(c, t))
            bars = ax.bar(xs, ys, w, color=colors[t], label=LABEL[t] if t != "voxd" else "voxd solid (whole command)")
            for b, h in zip(bars, hatch):
                if h:
                    b.set_hatch("///")
                    b.set_alpha(0.45)
        ax.set_yscale("log")
        ax.set_xticks(range(len(cs)))
        ax.set_xticklabels([c["mesh"].replace("stanford-", "").replace("2CylinderEngine", "2CylEngine") for c in cs],
                           rotation=30, ha="right", fontsize=8)
        ax.set_title(f"{r}³ (hatched: differs from reference)", fontsize=9)
        ax.set_ylabel("seconds (median)")
        ax.grid(axis="y", which="both", alpha=0.3)
    axes[0][0].legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    fig.savefig(a.out, dpi=110)


def cmd_report(a):
    doc = json.loads(Path(a.results).read_text())
    sys.stdout.write(report(doc))
