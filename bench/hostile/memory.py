#!/usr/bin/env python3
"""Peak RSS of `voxd serve` under the memory cases of issue 30 (on demand, not in CI).

Starts the server (the binary given, --max-memory 1 GiB by default), makes a large volume by
voxelizing a mesh at --resolution, then for each case reads the server's VmHWM from
/proc/PID/status after a fresh start: N concurrent GET /v1/volumes/{id}/stats (N = 1, 4, 16),
and a CSG body of 100 MB and 250 MB sent with Content-Length and chunked. Prints a table.

    python3 bench/hostile/memory.py --voxd target/release/voxd --mesh ../shared/meshes/stanford-bunny.obj
"""
import argparse, concurrent.futures as cf, http.client, os, re, subprocess, tempfile, time

def hwm(pid):
    s = open(f"/proc/{pid}/status").read()
    return {k: int(re.search(rf"{k}:\s+(\d+)", s).group(1)) * 1024 for k in ("VmHWM", "VmRSS")}

def start(args, data):
    p = subprocess.Popen([args.voxd, "serve", "--addr", "127.0.0.1:0", "--data-dir", data,
                          "--engine", "cpu", "--max-memory", str(args.max_memory)],
                         stdout=subprocess.PIPE, env={**os.environ, "VOXD_LOG": "warn"})
    line = p.stdout.readline().decode()
    addr = line.strip().split("http://")[1]
    return p, addr

def req(addr, method, path, body=None, headers=None, chunked=False):
    h, port = addr.split(":")
    c = http.client.HTTPConnection(h, int(port), timeout=600)
    c.request(method, path, body=body, headers=headers or {}, encode_chunked=chunked)
    r = c.getresponse()
    return r.status, r.read()

def csg_body(n):
    head, item = b'{"op":"union","operands":[', b'"0000000000000000000000000000000a",'
    return head + item * ((n - len(head)) // len(item)) + b'"x"]}'

def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--voxd", default="target/release/voxd")
    here = os.path.dirname(os.path.abspath(__file__))
    meshes = [os.path.join(here, "..", "..", "..", "shared", "meshes", "stanford-bunny.obj"),
              "/work/shared/meshes/stanford-bunny.obj", os.path.join(here, "..", "..", "tests", "data", "spot.obj")]
    ap.add_argument("--mesh", default=next((os.path.normpath(m) for m in meshes if os.path.exists(m)), meshes[0]))
    ap.add_argument("--resolution", type=int, default=1024)
    ap.add_argument("--max-memory", type=int, default=1 << 30)
    args = ap.parse_args()
    data = tempfile.mkdtemp(prefix="voxd-mem-")
    p, addr = start(args, data)
    fmt = os.path.splitext(args.mesh)[1].lstrip(".")
    st, b = req(addr, "POST", f"/v1/voxelize?format={fmt}&resolution={args.resolution}&wait=300",
                open(args.mesh, "rb").read())
    assert st == 201, b
    import json
    meta = json.loads(b)
    vid = meta["id"]
    print(f"volume {vid}: dims {meta['grid']['dims']}, stored {meta['bytes']} bytes")
    p.terminate(); p.wait()
    rows = []
    p, addr = start(args, data); time.sleep(0.5)
    rows.append(("idle server", "-", hwm(p.pid)["VmHWM"]))
    p.terminate(); p.wait()
    for n in (1, 4, 16):
        p, addr = start(args, data)
        with cf.ThreadPoolExecutor(n) as ex:
            sts = list(ex.map(lambda _: req(addr, "GET", f"/v1/volumes/{vid}/stats")[0], range(n)))
        rows.append((f"{n} x stats", ",".join(map(str, sorted(set(sts)))), hwm(p.pid)["VmHWM"]))
        p.terminate(); p.wait()
    for size in (100 << 20, 250 << 20):
        for chunked in (False, True):
            p, addr = start(args, data)
            body = csg_body(size)
            try:  # a 413 answered before the body is read may reach us as a broken pipe
                if chunked:
                    st, _ = req(addr, "POST", "/v1/volumes/csg",
                                iter([body[i:i + (1 << 20)] for i in range(0, len(body), 1 << 20)]),
                                {"Content-Type": "application/json"}, chunked=True)
                else:
                    st, _ = req(addr, "POST", "/v1/volumes/csg", body, {"Content-Type": "application/json"})
            except (BrokenPipeError, ConnectionResetError) as e:
                st = type(e).__name__
            rows.append((f"CSG {size >> 20} MB {'chunked' if chunked else 'Content-Length'}", st, hwm(p.pid)["VmHWM"]))
            p.terminate(); p.wait()
    print(f"{'case':32} {'status':>22} {'peak RSS MB':>12}")
    for c, s, m in rows:
        print(f"{c:32} {str(s):>22} {m / 1e6:12.1f}")
    import shutil
    shutil.rmtree(data, ignore_errors=True)

if __name__ == "__main__":
    main()
