#!/usr/bin/env python3
"""Tables and plots from bench/scaling/run.sh output directories.

Reads DIR/machine.txt and DIR/raw/*.{txt,meta} of each pass; writes results.json, tables.md and
img/scaling-{triangles,resolution,cpu-gpu,whole-command}.png into DEST (default: the one DIR).
With several passes (run.sh run more than once, e.g. PASSES=2) every cell gets, for each engine
on its own, the lowest of the passes' medians: on a shared machine other work only ever adds time.
Usage: report.py [--into DEST] DIR [DIR...]
"""
import glob
import json
import os
import re
import statistics
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

METHODS = ["solid", "surface", "conservative", "interior"]
COLORS = {"solid": "tab:blue", "surface": "tab:orange", "conservative": "tab:green", "interior": "tab:red"}
ENGINE_STYLE = {"cpu": ("-", "o"), "gpu": ("--", "s")}


def read_meta(path):
    meta = {}
    if os.path.exists(path):
        for line in open(path):
            if ":" in line:
                k, v = line.split(":", 1)
                meta[k.strip()] = v.strip()
    return meta


def num(s):
    try:
        return float(s)
    except (TypeError, ValueError):
        return None


def parse_bench(path):
    """Rows of a `voxd bench` table, and the header facts (gpu driver, cpu threads, runs)."""
    rows, head = [], {}
    for line in open(path):
        line = line.rstrip("\n")
        if line.startswith("gpu: "):
            m = re.search(r'driver: "([^"]*)"', line)
            head["gpu_driver"] = m.group(1) if m else line[5:]
            m = re.search(r'name: "([^"]*)"', line)
            head["gpu_name"] = m.group(1) if m else None
            m = re.search(r"opened in ([\d.]+) ms", line)
            head["gpu_open_ms"] = num(m.group(1)) if m else None
        elif line.startswith("cpu: "):
            head["cpu"] = line[5:]
        elif line.startswith("mesh: "):
            m = re.search(r"(\d+) triangles, loaded in ([\d.]+) ms", line)
            if m:
                head["triangles"], head["load_ms"] = int(m.group(1)), num(m.group(2))
        elif line.startswith("medians of "):
            head["runs"] = int(line.split()[2])
        elif line.startswith("| ") and not line.startswith("| method"):
            c = [x.strip() for x in line.strip().strip("|").split("|")]
            if len(c) < 4 or c[0] not in METHODS:
                continue
            r = {"method": c[0], "res": int(c[1].rstrip("³")), "snap": num(c[2]), "cpu": num(c[3])}
            if len(c) >= 10 and c[4]:
                r.update(gpu=num(c[4]), upload=num(c[5]), dispatch=num(c[6]), readback=num(c[7]),
                         identical=c[9])
            rows.append(r)
    return rows, head


def cells(out, prefix):
    """Bench cells from raw/<prefix>*.txt, with timeouts marked (cpu/gpu = None, *_over = T)."""
    result, heads = [], []
    for path in sorted(glob.glob(os.path.join(out, "raw", prefix + "*.txt"))):
        name = os.path.basename(path)[:-4]
        if name.endswith("-cpu"):
            continue
        meta = read_meta(path[:-4] + ".meta")
        rows, head = parse_bench(path)
        heads.append(head)
        rc, tmo = meta.get("rc"), num(meta.get("timeout_s"))
        timed_out = rc in ("124", "137")
        # The cells this call was meant to produce (from its name) that it did not print.
        expected = expected_cells(name, out)
        got = {(r["method"], r["res"]) for r in rows}
        for r in rows:
            r["runs"] = head.get("runs")
            r["triangles"] = head.get("triangles")
            r["load_before"], r["load_after"] = meta.get("load_before"), meta.get("load_after")
        for meth, res in expected:
            if (meth, res) in got:
                continue
            r = {"method": meth, "res": res, "snap": None, "cpu": None, "gpu": None,
                 "triangles": head.get("triangles"), "runs": head.get("runs"),
                 "error": None if timed_out else f"rc {rc}: " + open(path[:-4] + ".err").read().strip()[-300:]}
            if timed_out:
                r["cpu_over"] = r["gpu_over"] = tmo
            cpu_path = path[:-4] + "-cpu.txt"
            if os.path.exists(cpu_path):
                crow = [x for x in parse_bench(cpu_path)[0] if (x["method"], x["res"]) == (meth, res)]
                cmeta = read_meta(cpu_path[:-4] + ".meta")
                if crow:
                    r["cpu"], r["snap"] = crow[0]["cpu"], crow[0]["snap"]
                    r.pop("cpu_over", None)
                elif cmeta.get("rc") in ("124", "137"):
                    r["cpu_over"] = num(cmeta.get("timeout_s"))
            rows.append(r)
        for r in rows:
            r["call"] = name
        result += rows
    return result, heads


SETTINGS = {}


def expected_cells(name, out):
    methods = SETTINGS["METHODS"].split(",")
    m = re.fullmatch(r"tri-(\d+)-(\d+)", name)
    if m:
        return [(x, int(m.group(2))) for x in methods]
    m = re.fullmatch(r"res-(\d+)-([a-z]+)", name)
    if m:
        return [(m.group(2), int(m.group(1)))]
    m = re.fullmatch(r"res-(\d+)", name)
    if m:
        return [(x, int(m.group(1))) for x in methods]
    return []


def parse_whole(out):
    rx = re.compile(r"^(\w+) wall ([\d.e-]+) :: .*?, ([\d.]+) s \(load ([\d.]+), diagnose ([\d.]+), "
                    r"voxelize ([\d.]+), write ([\d.]+)\)")
    res = []
    for path in sorted(glob.glob(os.path.join(out, "raw", "whole-*.txt"))):
        m = re.fullmatch(r"whole-(\d+)-(\d+)", os.path.basename(path)[:-4])
        tris, grid = int(m.group(1)), int(m.group(2))
        meta = read_meta(path[:-4] + ".meta")
        runs = {}
        for line in open(path):
            mm = rx.match(line)
            if mm:
                runs.setdefault(mm.group(1), []).append([float(x) for x in mm.groups()[1:]])
        for meth, rs in runs.items():
            med = [statistics.median(c) for c in zip(*rs)]
            res.append({"triangles": tris, "res": grid, "method": meth, "runs": len(rs),
                        "wall": med[0], "summary_total": med[1], "load": med[2], "diagnose": med[3],
                        "voxelize": med[4], "write": med[5], "rc": meta.get("rc"),
                        "load_before": meta.get("load_before"), "load_after": meta.get("load_after")})
    return res


def fmt_ms(v, over=None):
    if v is None:
        return f"> {over / 1000:.0f} s" if over else "—"
    if v >= 10000:
        return f"{v / 1000:.1f} s"
    return f"{v:,.1f}" if v < 1000 else f"{v:,.0f}"


def gpu_cell(r):
    g = fmt_ms(r.get("gpu"), r.get("gpu_over") and r["gpu_over"] * 1000)
    if r.get("gpu") is not None and r.get("cpu") is not None and r["gpu"] < r["cpu"]:
        g = f"**{g}**"
    return g


def cpu_cell(r):
    return fmt_ms(r.get("cpu"), r.get("cpu_over") and r["cpu_over"] * 1000)


def ident(rs):
    vals = {r.get("identical") for r in rs if r.get("gpu") is not None}
    if not vals:
        return "—"
    return "yes" if vals == {"yes"} else "NO"


def table(rows, key, methods, keyname, keyfmt, extra=None):
    lines = []
    hdr = [keyname] + ([extra[0]] if extra else []) + ["snap"]
    for m in methods:
        hdr += [f"{m} cpu", f"{m} gpu"]
    hdr += ["runs", "identical"]
    lines.append("| " + " | ".join(hdr) + " |")
    lines.append("|" + "---|" * len(hdr))
    for k in sorted({key(r) for r in rows}):
        rs = [r for r in rows if key(r) == k]
        by = {r["method"]: r for r in rs}
        snaps = [r["snap"] for r in rs if r.get("snap") is not None]
        c = [keyfmt(k)] + ([extra[1](k)] if extra else []) + [fmt_ms(snaps[0]) if snaps else "—"]
        for m in methods:
            r = by.get(m, {})
            c += [cpu_cell(r), gpu_cell(r)]
        runs = sorted({r.get("runs") for r in rs if r.get("runs")})
        c += ["/".join(map(str, runs)) or "—", ident(rs)]
        lines.append("| " + " | ".join(c) + " |")
    return "\n".join(lines)


def merge(passes, key):
    """One row per key: per engine (and snap, and each phase) the lowest of the passes' values."""
    by = {}
    for i, rows in enumerate(passes):
        for r in rows:
            by.setdefault(key(r), []).append((i, r))
    out = []
    for k, rs in by.items():
        m = dict(rs[0][1])
        for f in ("snap", "cpu", "gpu", "upload", "dispatch", "readback", "wall", "summary_total", "load",
                  "diagnose", "voxelize", "write"):
            vals = [r[f] for _, r in rs if r.get(f) is not None]
            if f in m or vals:
                m[f] = min(vals) if vals else None
        for eng in ("cpu", "gpu"):
            overs = [r.get(eng + "_over") for _, r in rs if r.get(eng) is None and r.get(eng + "_over")]
            m.pop(eng + "_over", None)
            if m.get(eng) is None and overs:
                m[eng + "_over"] = max(overs)
        idents = {r.get("identical") for _, r in rs if r.get("gpu") is not None}
        if idents:
            m["identical"] = "yes" if idents == {"yes"} else "NO"
        m["passes"] = len(rs)
        m["per_pass"] = [{f: r.get(f) for f in ("cpu", "gpu", "wall", "runs") if f in r} for _, r in rs]
        # In how many passes the GPU engine was the faster one.
        m["gpu_faster_passes"] = sum(1 for _, r in rs if r.get("gpu") and r.get("cpu") and r["gpu"] < r["cpu"])
        out.append(m)
    return out


def main():
    args = sys.argv[1:]
    dest = None
    if args[:1] == ["--into"]:
        dest, args = args[1], args[2:]
    dirs = args
    out = dest or dirs[0]
    machines = [read_meta(os.path.join(d, "machine.txt")) for d in dirs]
    machine = machines[0]
    for kv in machine.get("settings", "").split():
        k, v = kv.split("=", 1)
        SETTINGS[k] = v
    methods = SETTINGS.get("METHODS", "solid,surface,conservative").split(",")
    SETTINGS.setdefault("METHODS", ",".join(methods))
    tris, ress, wholes, heads = [], [], [], []
    for d in dirs:
        t, h1 = cells(d, "tri-")
        r, h2 = cells(d, "res-")
        tris.append(t)
        ress.append(r)
        wholes.append(parse_whole(d))
        heads += h1 + h2
    cell_key = lambda r: (r["method"], r["res"], r.get("triangles"))  # noqa: E731
    tri = merge(tris, cell_key)
    res = merge(ress, cell_key)
    whole = merge(wholes, lambda w: (w["method"], w["res"], w["triangles"]))
    gpu = next((h for h in heads if h.get("gpu_driver")), {})
    cpu = next((h.get("cpu") for h in heads if h.get("cpu")), None)
    res_tris = next((r["triangles"] for r in res if r.get("triangles")), None)
    loads = [x for rows in tris + ress + wholes for r in rows for x in (r.get("load_before"), r.get("load_after")) if x]
    one_min = [float(x.split()[0]) for x in loads]
    os.makedirs(out, exist_ok=True)
    summary = {"passes": dirs, "machines": machines, "gpu": gpu, "cpu_threads": cpu, "triangle_series": tri,
               "resolution_series": res, "resolution_series_triangles": res_tris, "whole_command": whole,
               "load_1min_range": [min(one_min), max(one_min)] if one_min else None}
    with open(os.path.join(out, "results.json"), "w") as fh:
        json.dump(summary, fh, indent=1)

    md = []
    best = f" (the lowest of {len(dirs)} passes' medians, per engine)" if len(dirs) > 1 else ""
    md.append(f"Engine-only medians in ms (`voxd bench`){best}; gpu = {gpu.get('gpu_name')}, "
              f"{gpu.get('gpu_driver')}; cpu = {cpu}. **Bold**: the GPU engine faster than the CPU "
              "engine. `> T`: the call ran over its time limit.\n")
    for grid in sorted({r["res"] for r in tri}):
        md.append(f"### Triangle series at {grid}³\n")
        md.append(table([r for r in tri if r["res"] == grid], lambda r: r["triangles"] or 0, methods,
                        "triangles", lambda k: f"{k:,}"))
        md.append("")
    md.append(f"### Resolution series (igea, {res_tris:,} triangles)\n" if res_tris else "### Resolution series\n")
    md.append(table(res, lambda r: r["res"], methods, "grid", lambda k: f"{k}³",
                    extra=("voxels", lambda k: f"{k ** 3 / 1e6:,.2f} M" if k ** 3 < 1e9 else f"{k ** 3 / 1e9:.2f} G")))
    md.append("")
    if whole:
        md.append(f"### Whole command, CPU engine, {whole[0]['res']}³ (`voxd voxelize --engine cpu`, seconds)\n")
        md.append("| triangles | method | wall clock | load | diagnose | voxelize | write | runs |")
        md.append("|---|---|---|---|---|---|---|---|")
        for w in sorted(whole, key=lambda w: (w["triangles"], methods.index(w["method"]) if w["method"] in methods else 9)):
            md.append(f"| {w['triangles']:,} | {w['method']} | {w['wall']:.3f} | {w['load']:.3f} | "
                      f"{w['diagnose']:.3f} | {w['voxelize']:.3f} | {w['write']:.3f} | {w['runs']} |")
        md.append("")
    wins = [r for r in tri + res if r.get("gpu_faster_passes")]
    md.append("### Cells where the GPU engine (lavapipe) was faster in at least one pass\n")
    if wins:
        md.append("| series | triangles | grid | method | cpu | gpu | cpu / gpu | passes where gpu was faster |")
        md.append("|---|---|---|---|---|---|---|---|")
        for r in sorted(wins, key=lambda r: (r["call"][:3], r["triangles"] or 0, r["res"], r["method"])):
            ratio = f"{r['cpu'] / r['gpu']:.2f}×" if r.get("cpu") and r.get("gpu") else "—"
            md.append(f"| {'triangles' if r['call'].startswith('tri') else 'resolution'} | {r['triangles']:,} | "
                      f"{r['res']}³ | {r['method']} | {fmt_ms(r.get('cpu'))} | {fmt_ms(r.get('gpu'))} | {ratio} | "
                      f"{r['gpu_faster_passes']} of {r['passes']} |")
    else:
        md.append("None.")
    md.append("")
    if one_min:
        md.append(f"1-minute load average over the measurement calls: {min(one_min):.2f}–{max(one_min):.2f}.\n")
    with open(os.path.join(out, "tables.md"), "w") as fh:
        fh.write("\n".join(md))
    print("\n".join(md))
    plots(out, tri, res, whole, methods, res_tris, gpu, cpu)


def series(rows, key, method, engine):
    pts = []
    for r in sorted(rows, key=key):
        if r["method"] != method:
            continue
        v = r.get(engine)
        if v is not None:
            pts.append((key(r), v, False))
        elif r.get(engine + "_over"):
            pts.append((key(r), r[engine + "_over"] * 1000, True))
    return pts


def draw(ax, rows, key, methods, ylabel, value=None):
    for m in methods:
        for eng, (ls, mk) in ENGINE_STYLE.items():
            pts = series(rows, key, m, eng)
            if value:
                pts = [(x, value(x, y), o) for x, y, o in pts]
            ok = [(x, y) for x, y, o in pts if not o]
            if ok:
                ax.plot(*zip(*ok), ls=ls, marker=mk, color=COLORS[m], ms=4,
                        label=f"{m}, {'CPU engine' if eng == 'cpu' else 'GPU engine (lavapipe)'}")
            over = [(x, y) for x, y, o in pts if o]
            if over:
                ax.plot(*zip(*over), ls="none", marker="^", color=COLORS[m], ms=8, mfc="none")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_ylabel(ylabel)
    ax.grid(True, which="both", alpha=0.3)


def plots(out, tri, res, whole, methods, res_tris, gpu, cpu):
    img = os.path.join(out, "img")
    os.makedirs(img, exist_ok=True)
    note = f"GPU engine: {gpu.get('gpu_driver', '?')} (CPU Vulkan); CPU engine: {cpu}"
    grids = sorted({r["res"] for r in tri})

    fig, axes = plt.subplots(1, len(grids), figsize=(6.5 * len(grids), 5), squeeze=False)
    for ax, g in zip(axes[0], grids):
        rows = [r for r in tri if r["res"] == g and r.get("triangles")]
        draw(ax, rows, lambda r: r["triangles"], methods, "engine time (ms)")
        snaps = sorted({(r["triangles"], r["snap"]) for r in rows if r.get("snap") is not None})
        if snaps:
            ax.plot(*zip(*snaps), ":", marker="x", color="grey", label="snap to the grid (shared, not in either)")
        xs = sorted({r["triangles"] for r in rows})
        last = [v for r in rows if r["triangles"] == xs[-1] for v in (r.get("cpu"), r.get("gpu")) if v]
        if len(xs) > 1 and last:
            y1 = min(last) / 2
            ax.plot([xs[0], xs[-1]], [y1 * xs[0] / xs[-1], y1], "-", lw=0.8, color="grey", label="∝ triangles")
        ax.set_xlabel("triangles (igea decimated / subdivided)")
        ax.set_title(f"{g}³ grid")
    axes[0][0].legend(fontsize=7)
    fig.suptitle("voxd engine time against triangle count\n" + note, fontsize=9)
    fig.tight_layout()
    fig.savefig(os.path.join(img, "scaling-triangles.png"), dpi=110)
    plt.close(fig)

    fig, axes = plt.subplots(1, 2, figsize=(13, 5))
    vox = lambda r: r["res"] ** 3  # noqa: E731
    draw(axes[0], res, vox, methods, "engine time (ms)")
    if res:
        xs = sorted({vox(r) for r in res})
        y0 = min(r["cpu"] for r in res if r.get("cpu") and vox(r) == xs[-1])
        axes[0].plot([xs[0], xs[-1]], [y0 * xs[0] / xs[-1] / 2, y0 / 2], "-", lw=0.8, color="grey", label="∝ voxels")
    axes[0].set_title(f"time (igea, {res_tris:,} triangles; ▲ = over the time limit)" if res_tris else "time")
    draw(axes[1], res, vox, methods, "throughput (voxels / s)", value=lambda x, y: x / (y / 1000))
    axes[1].set_title("throughput")
    for ax in axes:
        ax.set_xlabel("voxels (64³ … 2048³, cubic)")
    axes[0].legend(fontsize=7)
    fig.suptitle("voxd engine time against resolution\n" + note, fontsize=9)
    fig.tight_layout()
    fig.savefig(os.path.join(img, "scaling-resolution.png"), dpi=110)
    plt.close(fig)

    fig, axes = plt.subplots(1, 2, figsize=(13, 4.8))
    for g, mk in zip(grids, "os^D"):
        for m in methods:
            pts = sorted((r["triangles"], r["cpu"] / r["gpu"]) for r in tri
                         if r["res"] == g and r["method"] == m and r.get("cpu") and r.get("gpu"))
            if pts:
                axes[0].plot(*zip(*pts), marker=mk, color=COLORS[m], ls="-" if mk == "o" else "--",
                             label=f"{m}, {g}³")
    for m in methods:
        pts = sorted((vox(r), r["cpu"] / r["gpu"]) for r in res if r["method"] == m and r.get("cpu") and r.get("gpu"))
        if pts:
            axes[1].plot(*zip(*pts), marker="o", color=COLORS[m], label=m)
    for ax, xl in zip(axes, ["triangles", "voxels"]):
        ax.axhline(1, color="black", lw=1)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(xl)
        ax.set_ylabel("CPU time / GPU time (> 1: lavapipe faster)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    axes[0].set_title("against triangles")
    axes[1].set_title(f"against resolution (igea, {res_tris:,} triangles)" if res_tris else "against resolution")
    fig.suptitle("CPU engine time / lavapipe time\n" + note, fontsize=9)
    fig.tight_layout()
    fig.savefig(os.path.join(img, "scaling-cpu-gpu.png"), dpi=110)
    plt.close(fig)

    if whole:
        fig, ax = plt.subplots(figsize=(7, 5))
        for m in methods:
            pts = sorted((w["triangles"], w["wall"]) for w in whole if w["method"] == m)
            if pts:
                ax.plot(*zip(*pts), "-o", color=COLORS[m], ms=4, label=f"whole command, {m}")
            pts = sorted((w["triangles"], w["voxelize"]) for w in whole if w["method"] == m)
            if pts:
                ax.plot(*zip(*pts), "--", marker=".", color=COLORS[m], label=f"voxelize phase, {m}")
        for ph, c in [("load", "black"), ("diagnose", "grey"), ("write", "tab:purple")]:
            pts = sorted((w["triangles"], w[ph]) for w in whole if w["method"] == methods[0])
            if pts:
                ax.plot(*zip(*pts), ":", marker="x", color=c, label=f"{ph} phase")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("triangles")
        ax.set_ylabel("seconds")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
        ax.set_title(f"voxd voxelize --engine cpu, {whole[0]['res']}³ (whole command and its phases)", fontsize=9)
        fig.tight_layout()
        fig.savefig(os.path.join(img, "scaling-whole-command.png"), dpi=110)
        plt.close(fig)


if __name__ == "__main__":
    main()
