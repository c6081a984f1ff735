#!/usr/bin/env python3
"""Peak memory (VmHWM) of `voxd serve` under concurrent hostile and real uploads (on demand, not
in CI; issue 30, defect 2, uploads half).

Cases, each sent 1, 4 and 16 times at once to a fresh server (so VmHWM is that round's peak):
  (a) a gzip binary STL of 20 M degenerate triangles (all corners at 0,0,0): 1 GB decoded;
  (b) a gzip OBJ of 60 M `v 0 0 0` lines (480 MB decoded, the vertex limit);
  (c) a real mesh from shared/meshes (igea.obj, 10 MB, 268 k triangles).

Usage: upload_memory.py BINARY [--max-memory BYTES] [--label NAME]
Prints one row per case and concurrency: statuses seen and the peak RSS in MiB.
"""
import argparse
import http.client
import os
import subprocess
import sys
import tempfile
import threading
import time
import zlib

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def gz_stream(chunks):
    c = zlib.compressobj(1, zlib.DEFLATED, 31)
    out = [c.compress(ch) for ch in chunks]
    out.append(c.flush())
    return b"".join(out)


def stl_bomb(n):
    def chunks():
        yield bytes(80) + n.to_bytes(4, "little")
        block = bytes(50 * 100_000)
        for _ in range(n // 100_000):
            yield block
        yield bytes(50 * (n % 100_000))
    return gz_stream(chunks())


def obj_bomb(n):
    def chunks():
        block = b"v 0 0 0\n" * 1_000_000
        for _ in range(n // 1_000_000):
            yield block
        yield b"f 1 2 3\n"
    return gz_stream(chunks())


def vm_hwm(pid):
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) * 1024
    return 0


def start(binary, max_memory, data):
    args = [binary, "serve", "--addr", "127.0.0.1:0", "--engine", "cpu", "--data-dir", data]
    if max_memory:
        args += ["--max-memory", str(max_memory)]
    p = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                         env=dict(os.environ, VOXD_LOG="warn"))
    line = p.stdout.readline().decode().strip()
    addr = line.removeprefix("voxd listening on http://")
    return p, addr


def post(addr, body, ctype, out):
    host, port = addr.rsplit(":", 1)
    try:
        c = http.client.HTTPConnection(host, int(port), timeout=600)
        c.request("POST", "/v1/voxelize?resolution=32&wait=300", body,
                  {"Content-Type": ctype, "Content-Encoding": "gzip"} if body[:2] == b"\x1f\x8b"
                  else {"Content-Type": ctype})
        r = c.getresponse()
        r.read()
        out.append(r.status)
    except Exception as e:  # a refused or reset connection is a result too
        out.append(type(e).__name__)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("binary")
    ap.add_argument("--max-memory", type=int, default=2 << 30)
    ap.add_argument("--label", default="")
    ap.add_argument("--copies", default="1,4,16")
    a = ap.parse_args()
    if not os.path.exists(a.binary):
        sys.exit(f"no binary at {a.binary}")
    igea = os.path.join(ROOT, "..", "shared", "meshes", "igea.obj")
    if not os.path.exists(igea):
        igea = "/work/shared/meshes/igea.obj"
    cases = [
        ("(a) STL 20M degenerate", stl_bomb(20_000_000), "model/stl"),
        ("(b) OBJ 60M v lines", obj_bomb(60_000_000), "model/obj"),
        ("(c) igea.obj", open(igea, "rb").read(), "model/obj"),
    ]
    print("| build | case | body | copies | statuses | peak RSS (MiB) | seconds |")
    print("|---|---|---|---|---|---|---|")
    for name, body, ctype in cases:
        for n in [int(x) for x in a.copies.split(",")]:
            with tempfile.TemporaryDirectory() as data:
                p, addr = start(a.binary, a.max_memory, data)
                try:
                    out, ts = [], []
                    t0 = time.time()
                    for _ in range(n):
                        t = threading.Thread(target=post, args=(addr, body, ctype, out))
                        t.start()
                        ts.append(t)
                    for t in ts:
                        t.join()
                    dt = time.time() - t0
                    peak = vm_hwm(p.pid)
                finally:
                    p.kill()
                    p.wait()
            counts = {}
            for s in out:
                counts[s] = counts.get(s, 0) + 1
            st = " ".join(f"{k}×{v}" for k, v in sorted(counts.items(), key=str))
            print(f"| {a.label} | {name} | {len(body) / 1e6:.2f} MB | {n} | {st} | "
                  f"{peak / 2**20:.0f} | {dt:.1f} |", flush=True)


if __name__ == "__main__":
    main()
