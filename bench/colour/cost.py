"""The cost of colour (issue 34), side by side in one run: `voxd voxelize` of the same mesh on the
same grid without and with `--color`, alternating, best of N runs each; and the time of a 512³
coloured volume's `.vox` (palette and split into models). Meshes: Fox.glb (tests/data) and
igea-subdiv4 with a 4096² texture, procedural and a photograph (`textured.py`, made once into
the output folder). Prints a markdown table and writes results.json.

    python bench/colour/cost.py --voxd target/release/voxd --out DIR [--runs 3] [--resolution 256]
"""
import argparse, json, re, subprocess, sys, time
from pathlib import Path

here = Path(__file__).resolve().parent
root = here.parent.parent


def run(cmd):
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True, env={"VOXD_LOG": "info", "PATH": "/usr/bin:/bin"})
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        sys.exit(f"{cmd}: {r.stderr[-2000:]}")
    return wall, r.stdout + r.stderr


def main():
    a = argparse.ArgumentParser()
    a.add_argument("--voxd", required=True)
    a.add_argument("--out", required=True)
    a.add_argument("--runs", type=int, default=3)
    a.add_argument("--resolution", type=int, default=256)
    a.add_argument("--meshes-dir", default=str(root.parent / "shared" / "meshes"))
    a = a.parse_args()
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    meshes = [("Fox.glb", root / "tests" / "data" / "Fox.glb")]
    igea = Path(a.meshes_dir) / "igea-subdiv4.obj.gz"
    if igea.exists():
        for kind in ("procedural", "photo"):
            glb = out / f"igea-{kind}.glb"
            if not glb.exists():
                subprocess.run([sys.executable, str(here / "textured.py"), str(igea), str(glb), "4096", kind], check=True)
            meshes.append((f"igea-subdiv4, 4096² {kind} texture", glb))
    else:
        print(f"notice: {igea} is absent; only Fox.glb is measured", file=sys.stderr)
    rows = []
    for name, path in meshes:
        for method in ("surface", "solid"):
            best = {}
            for _ in range(a.runs):
                for colour in (False, True):
                    cmd = [a.voxd, "voxelize", str(path), "-o", str(out / "v.vxl"), "--resolution",
                           str(a.resolution), "--method", method] + (["--color"] if colour else [])
                    wall, text = run(cmd)
                    best[colour] = min(best.get(colour, wall), wall)
            rows.append({"mesh": name, "method": method, "plain_s": best[False], "color_s": best[True],
                         "ratio": best[True] / best[False]})
    vox = None
    if len(meshes) > 1:
        # The .vox writer alone: the write phase `voxd voxelize -o x.vox` reports (palette,
        # split, file); and `voxd convert` of the stored .vxl, whole command (reading it too).
        src = out / "v512.vxl"
        run([a.voxd, "voxelize", str(meshes[-1][1]), "-o", str(src), "--resolution", "512", "--method", "solid", "--color"])
        writes, converts = [], []
        for _ in range(a.runs):
            _, text = run([a.voxd, "voxelize", str(meshes[-1][1]), "-o", str(out / "w512.vox"), "--resolution", "512",
                           "--method", "solid", "--color"])
            writes.append(float(re.search(r"write ([0-9.]+)", text).group(1)))
            wall, text = run([a.voxd, "convert", str(src), str(out / "v512.vox")])
            converts.append(wall)
        m = re.search(r"mean_delta_e=([0-9.]+) p99_delta_e=([0-9.]+)", text)
        vox = {"mesh": meshes[-1][0], "write_s": min(writes), "convert_s": min(converts),
               "bytes": (out / "v512.vox").stat().st_size,
               "mean_de": float(m.group(1)) if m else None, "p99_de": float(m.group(2)) if m else None}
    (out / "results.json").write_text(json.dumps({"rows": rows, "vox": vox, "voxd": a.voxd}, indent=1))
    print(f"| mesh | method at {a.resolution}³ | without colour | with --color | ratio (target ≤ 1.5) |")
    print("|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['mesh']} | {r['method']} | {r['plain_s']:.3f} s | {r['color_s']:.3f} s | {r['ratio']:.2f}× |")
    if vox:
        print(f"\n.vox of the 512³ solid of {vox['mesh']}: written in {vox['write_s']:.3f} s (target under 1 s), "
              f"`voxd convert` from the .vxl {vox['convert_s']:.3f} s (whole command); {vox['bytes']} bytes, "
              f"palette ΔE76 mean {vox['mean_de']:.2f} / p99 {vox['p99_de']:.2f}")


main()
