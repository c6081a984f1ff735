#!/usr/bin/env python3
"""Replay the hostile request classes of issue 30 against `voxd serve` and print one table row per
case: the class, what was sent, the statuses seen, the wall time and the server's peak RSS
(VmHWM from /proc, when this script started the server, or was given its --pid).

Classes (--classes, comma-separated; all by default):
  flood   N idle sockets + N half-sent heads held from 127.0.0.2 (reopened whenever the server
          closes them), for N in --flood-sizes, with --max-connections-per-client 0 and the
          default; meanwhile 127.0.0.1 sends GET /healthz every 0.5 s for --probe-seconds after
          the flood is up: max / median latency and how many took over 1 s.
  memory  the cases of memory.py and upload_memory.py, each with 1, 4 and 16 concurrent copies on
          a fresh server with --max-memory (default 1 GiB): N x GET /v1/volumes/{id}/stats of a
          large volume (also 40 at once), CSG bodies of 100 MB and 250 MB (Content-Length and
          chunked), a gzip binary STL of 20 M degenerate triangles, a gzip OBJ of 60 M `v 0 0 0`
          lines and a real mesh (igea.obj). Peak RSS against the budget plus the idle baseline.
  slow    11 clients read GET /v1/volumes/{id}/data?format=npy at ~100 KB/s, holding the
          conversions' memory; then a fast client's normal 2.4 MB upload must be 201 or 503
          (never 408).
  old     oversized heads (431), a declared body over the limit (413), Expect: 200-ok (417), a
          Content-Encoding: gzip body that is not gzip (problem), a half-sent head, a stalled and a
          dripping body (408).

Python 3 standard library only. Every request has a timeout; the default pass took 7 minutes
on two cores shared with a build (dev-profile binary), --quick about 1.5.

    python3 bench/hostile/hostile.py --voxd /tmp/voxd-bench
    python3 bench/hostile/hostile.py --voxd target/release/voxd --quick
    python3 bench/hostile/hostile.py --addr 127.0.0.1:8080 --pid 1234 --classes old,slow
"""
import argparse
import concurrent.futures as cf
import errno
import json
import multiprocessing as mp
import os
import resource
import select
import shutil
import socket
import statistics
import sys
import tempfile
import threading
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, HERE)
from memory import csg_body  # noqa: E402
from upload_memory import obj_bomb, stl_bomb  # noqa: E402
from hostile_http import MiB, Server, request, raw, slow_reader  # noqa: E402

IP_BIND_ADDRESS_NO_PORT = 24  # linux/in.h
HALF_HEAD = b"GET / HTTP/1.1\r\nHost: x\r\n"  # no final CRLF: the head never ends


def raise_nofile():
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft < hard:
        resource.setrlimit(resource.RLIMIT_NOFILE, (hard, hard))
    return resource.getrlimit(resource.RLIMIT_NOFILE)[0]


def find_mesh(*names):
    for d in (os.path.join(ROOT, "..", "shared", "meshes"), "/work/shared/meshes",
              os.path.join(ROOT, "tests", "data")):
        for n in names:
            p = os.path.join(d, n)
            if os.path.exists(p):
                return os.path.normpath(p)
    return None


def count(keys):
    c = {}
    for k in keys:
        c[k] = c.get(k, 0) + 1
    return " ".join(f"{k}×{v}" for k, v in sorted(c.items(), key=lambda kv: str(kv[0])))


def mb(b):
    return "-" if b is None else f"{b / MiB:.0f}"


class Table:
    def __init__(self):
        print("| class | sent | statuses | time (s) | peak RSS (MiB) | notes |", flush=True)
        print("|---|---|---|---|---|---|", flush=True)
        self.rows = []

    def row(self, cls, sent, statuses, secs, peak, notes=""):
        r = (cls, sent, statuses, f"{secs:.1f}", mb(peak), notes)
        self.rows.append(r)
        print("| " + " | ".join(r) + " |", flush=True)


# ---------------------------------------------------------------------------------------------
# flood


def holder(kind, n, addr, src, conn, ramp_limit):
    """Hold n connections from src to addr (kind: idle or half), reopening each one the server
    closes, until told to stop; report counts."""
    raise_nofile()
    host, port = addr.rsplit(":", 1)
    port = int(port)
    ep = select.epoll()
    socks = {}  # fd -> [socket, connected, initial]
    st = {"opened": 0, "connected": 0, "closed_by_server": 0, "connect_errors": {}, "answers": {},
          "initial_done": 0, "open_errors": {}}
    reopen = 0

    def bump(d, k):
        d[k] = d.get(k, 0) + 1

    def open_one(initial):
        try:
            s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        except OSError as e:
            bump(st["open_errors"], errno.errorcode.get(e.errno, str(e.errno)))
            return False
        s.setblocking(False)
        try:
            s.setsockopt(socket.SOL_IP, IP_BIND_ADDRESS_NO_PORT, 1)
            s.bind((src, 0))
        except OSError as e:
            bump(st["open_errors"], errno.errorcode.get(e.errno, str(e.errno)))
            s.close()
            return False
        rc = s.connect_ex((host, port))
        if rc not in (0, errno.EINPROGRESS):
            bump(st["open_errors"], errno.errorcode.get(rc, str(rc)))
            s.close()
            return False
        socks[s.fileno()] = [s, False, initial]
        ep.register(s.fileno(), select.EPOLLOUT | select.EPOLLRDHUP)
        st["opened"] += 1
        return True

    def drop(fd):
        s, _, initial = socks.pop(fd)
        ep.unregister(fd)
        s.close()
        if initial:
            st["initial_done"] += 1

    t0 = time.monotonic()
    to_open, ready = n, False
    while True:
        if conn.poll():
            if conn.recv() == "stop":
                break
        k = min(to_open, 250)
        for _ in range(k):
            if not open_one(True):
                st["initial_done"] += 1  # counted as done: it will not come
        to_open -= k
        k = min(reopen, 250)
        for _ in range(k):
            open_one(False)
        reopen -= k
        for fd, ev in ep.poll(0.01 if (to_open or reopen) else 0.2):
            ent = socks.get(fd)
            if ent is None:
                continue
            s, connected, initial = ent
            if not connected:
                err = s.getsockopt(socket.SOL_SOCKET, socket.SO_ERROR)
                if err or ev & (select.EPOLLERR | select.EPOLLHUP):
                    bump(st["connect_errors"], errno.errorcode.get(err, str(err)) if err else "hup")
                    drop(fd)
                    reopen += 1
                    continue
                ent[1] = True
                st["connected"] += 1
                if initial:
                    ent[2] = False
                    st["initial_done"] += 1
                if kind == "half":
                    try:
                        s.send(HALF_HEAD)
                    except OSError:
                        st["closed_by_server"] += 1
                        drop(fd)
                        reopen += 1
                        continue
                ep.modify(fd, select.EPOLLIN | select.EPOLLRDHUP)
                continue
            try:
                d = s.recv(4096)
            except OSError:
                d = b""
            if d:
                if d.startswith(b"HTTP/1."):
                    bump(st["answers"], d.split(b" ", 2)[1].decode("latin-1", "replace"))
                if not ev & (select.EPOLLRDHUP | select.EPOLLHUP):
                    continue
            st["closed_by_server"] += 1
            drop(fd)
            reopen += 1
        if not ready and (st["initial_done"] >= n or time.monotonic() - t0 > ramp_limit):
            ready = True
            conn.send(("ready", time.monotonic() - t0, sum(1 for e in socks.values() if e[1])))
    st["held_at_end"] = sum(1 for e in socks.values() if e[1])
    for fd in list(socks):
        drop(fd)
    if not ready:
        conn.send(("ready", time.monotonic() - t0, 0))
    conn.send(("done", st))


def probe(addr, out, t_sched):
    host, port = addr.rsplit(":", 1)
    t = time.monotonic()
    r = request(addr, "GET", "/healthz", timeout=10, src="127.0.0.1")
    out.append((t_sched, time.monotonic() - t, r.key))


def flood_round(a, tab, n, per_client):
    extra = [] if per_client is None else ["--max-connections-per-client", per_client]
    srv = Server(a, extra)
    t0 = time.monotonic()
    try:
        ctx = mp.get_context("fork")
        kids = []
        for kind in ("idle", "half"):
            pa, pb = ctx.Pipe()
            p = ctx.Process(target=holder, args=(kind, n, srv.addr, "127.0.0.2", pb, a.ramp_limit),
                            daemon=True)
            p.start()
            kids.append((kind, p, pa))
        probes, threads, ramp, fdmax = [], [], {}, 0
        start, interval, ready_at = time.monotonic(), 0.5, None
        i = 0
        while True:
            now = time.monotonic()
            if ready_at is None:
                for kind, _, pa in kids:
                    if kind not in ramp and pa.poll():
                        msg = pa.recv()
                        ramp[kind] = msg[1:]
                if len(ramp) == 2:
                    ready_at = now
            if ready_at is not None and now - ready_at >= a.probe_seconds:
                break
            if now - start > a.ramp_limit + a.probe_seconds + 10:
                break
            phase = "held" if ready_at is not None else "ramp"
            th = threading.Thread(target=probe, args=(srv.addr, probes, (phase, now - start)),
                                  daemon=True)
            th.start()
            threads.append(th)
            fdmax = max(fdmax, srv.fds() or 0)
            i += 1
            time.sleep(max(0.0, start + i * interval - time.monotonic()))
        for th in threads:
            th.join(12)
        stats = {}
        for kind, p, pa in kids:
            pa.send("stop")
            while pa.poll(30):
                msg = pa.recv()
                if msg[0] == "done":
                    stats[kind] = msg[1]
                    break
            p.join(10)
            if p.is_alive():
                p.kill()
        dt = time.monotonic() - t0
        peak = srv.hwm()
    finally:
        srv.stop()
    held = [p for p in probes if p[0][0] == "held"]
    lat = sorted(x[1] for x in held)
    over = sum(1 for x in held if x[1] > 1.0 or x[2] != "200")
    allmax = max((x[1] for x in probes), default=0)
    cap = "per-client 0 (off)" if per_client == 0 else "per-client default (256)"
    sent = f"{n} idle + {n} half-sent heads from 127.0.0.2, {cap}"
    notes = (f"healthz while held: n={len(held)} median {statistics.median(lat) if lat else 0:.3f} s, "
             f"max {max(lat) if lat else 0:.3f} s, >1 s or not 200: {over}; "
             f"ramp {max((r[0] for r in ramp.values()), default=0):.1f} s "
             f"(probes during ramp: {len(probes) - len(held)}, max {allmax:.3f} s); server fds max {fdmax}; ")
    for kind in ("idle", "half"):
        s = stats.get(kind, {})
        notes += (f"{kind}: opened {s.get('opened', '?')}, closed by server {s.get('closed_by_server', '?')}, "
                  f"held at end {s.get('held_at_end', '?')}")
        if s.get("answers"):
            notes += f", answers {s['answers']}"
        if s.get("connect_errors") or s.get("open_errors"):
            notes += f", errors {s.get('connect_errors')} {s.get('open_errors')}"
        notes += "; "
    tab.row("flood", sent, "healthz " + count(p[2] for p in held), dt, peak, notes.rstrip("; "))


def flood_class(a, tab):
    nofile = raise_nofile()
    print(f"<!-- flood: this process's RLIMIT_NOFILE {nofile} (each holder process opens N) -->", flush=True)
    for n in a.flood_sizes:
        for per_client in (0, None):
            flood_round(a, tab, n, per_client)


# ---------------------------------------------------------------------------------------------
# memory


def make_volume(a):
    """A large stored volume (voxelize --mesh at --resolution); returns (data_dir, id, meta)."""
    data = None if a.addr else tempfile.mkdtemp(prefix="voxd-hostile-vol-")
    srv = Server(a, data=data)
    try:
        fmt = os.path.splitext(a.mesh)[1].lstrip(".")
        t = time.monotonic()
        r = request(srv.addr, "POST", f"/v1/voxelize?format={fmt}&resolution={a.resolution}&wait=300",
                    open(a.mesh, "rb").read(), timeout=600)
        if r.status != 201:
            raise RuntimeError(f"voxelize: {r.key} {r.body[:300]!r}")
        meta = json.loads(r.body)
        print(f"<!-- volume {meta['id']}: {os.path.basename(a.mesh)} at {a.resolution}, dims "
              f"{meta['grid']['dims']}, {meta['solid_voxels']} solid voxels, stored "
              f"{meta.get('bytes', '?')} bytes, {time.monotonic() - t:.1f} s -->", flush=True)
    finally:
        srv.stop()
    return data, meta["id"], meta


def idle_baseline(a):
    """The fixed overhead: VmHWM of a fresh, idle server."""
    if a.addr:
        return None
    srv = Server(a)
    time.sleep(2)
    try:
        return srv.hwm()
    finally:
        srv.stop()


def over_note(peak, budget, overhead):
    if peak is None or overhead is None:
        return ""
    lim = budget + overhead
    return (f"; under budget + overhead ({mb(lim)} MiB)" if peak <= lim
            else f"; OVER budget + overhead ({mb(lim)} MiB) by {mb(peak - lim)} MiB")


def concurrent(n, fn):
    with cf.ThreadPoolExecutor(n) as ex:
        return list(ex.map(lambda _: fn(), range(n)))


def memory_round(a, tab, cls, sent, n, fn, data=None, overhead=None, budget=None):
    budget = budget or a.max_memory
    saved, a.max_memory = a.max_memory, budget
    try:
        srv = Server(a, data=data)
    finally:
        a.max_memory = saved
    try:
        t = time.monotonic()
        res = concurrent(n, lambda: fn(srv.addr))
        dt = time.monotonic() - t
        peak = srv.hwm()
    finally:
        srv.stop()
    probs = count(r.problem for r in res if r.problem)
    notes = ((f"problems {probs}" if probs else "") + over_note(peak, budget, overhead)).lstrip("; ")
    tab.row(cls, f"{n} × {sent}", count(r.key for r in res), dt, peak, notes)
    return peak


def memory_class(a, tab):
    overhead = a.overhead
    tab.row("memory", "idle server (baseline)", "-", 2, overhead,
            f"budget --max-memory {a.max_memory} ({a.max_memory / MiB:.0f} MiB)")
    data, vid, meta = make_volume(a)
    dims = "x".join(map(str, meta["grid"]["dims"]))
    try:
        for n in a.stats_copies:
            memory_round(a, tab, "memory", f"GET stats ({dims} volume)", n,
                         lambda addr: request(addr, "GET", f"/v1/volumes/{vid}/stats", timeout=600),
                         data=data, overhead=overhead)
        for size in a.csg_sizes:
            body = csg_body(size * MiB)
            for chunked in (False, True):
                for n in a.copies:
                    memory_round(a, tab, "memory",
                                 f"CSG body {size} MB {'chunked' if chunked else 'Content-Length'}", n,
                                 lambda addr: request(addr, "POST", "/v1/volumes/csg", body,
                                                      {"Content-Type": "application/json"},
                                                      timeout=300, chunked=chunked),
                                 overhead=overhead)
            del body
    finally:
        if data:
            shutil.rmtree(data, ignore_errors=True)
    igea = find_mesh("igea.obj")
    cases = [("gzip STL, 20 M degenerate triangles", lambda: stl_bomb(20_000_000), "model/stl", True),
             ("gzip OBJ, 60 M `v 0 0 0` lines", lambda: obj_bomb(60_000_000), "model/obj", True)]
    if igea:
        cases.append(("igea.obj (real mesh, 268 k triangles)", lambda: open(igea, "rb").read(), "model/obj", False))
    for name, make, ctype, gz in cases:
        body = make()
        hdr = {"Content-Type": ctype, **({"Content-Encoding": "gzip"} if gz else {})}
        # the bombs' parse estimates (about 5.1 and 3.9 GB) are over a 1 GiB budget, so they are
        # refused at once (422); --bomb-budget admits them, one at a time
        budgets = [a.max_memory] + ([a.bomb_budget] if gz and a.bomb_budget and not a.addr else [])
        for budget in budgets:
            for n in a.copies:
                memory_round(a, tab, "memory", f"{name} ({len(body) / 1e6:.1f} MB), resolution 32"
                             + (f", --max-memory {budget / MiB:.0f} MiB" if budget != a.max_memory else ""), n,
                             lambda addr: request(addr, "POST", "/v1/voxelize?resolution=32&wait=300", body,
                                                  hdr, timeout=400),
                             overhead=overhead, budget=budget)


# ---------------------------------------------------------------------------------------------
# slow download readers


def conversion_cost(meta):
    """The budget a .npy download of a bit volume holds (src/app/cost.rs, conversion): the stored
    bytes, the decoded volume (a u64 per 64 voxels of a z column) and 1 MiB of chunks."""
    nx, ny, nz = meta["grid"]["dims"]
    return meta["bytes"] + nx * ny * ((nz + 63) // 64) * 8 + 4 * (256 << 10)


def slow_round(a, tab, data, vid, meta, budget, label):
    saved = a.max_memory
    a.max_memory = budget
    srv = Server(a, data=data)
    a.max_memory = saved
    t0 = time.monotonic()
    try:
        stop = threading.Event()
        out = [None] * a.readers
        ths = [threading.Thread(target=slow_reader, daemon=True,
                                args=(srv.addr, f"/v1/volumes/{vid}/data?format=npy", a.reader_rate, stop, out, i))
               for i in range(a.readers)]
        for th in ths:
            th.start()
        # every reader has its answer (a 503 comes after the 5 s memory wait) or 20 s passed
        while time.monotonic() - t0 < 20 and any(o is None for o in out):
            time.sleep(0.2)
        time.sleep(1)
        rss_readers = srv.rss()
        bunny = find_mesh("stanford-bunny.obj")
        body = open(bunny, "rb").read()
        t = time.monotonic()
        up = request(srv.addr, "POST", "/v1/voxelize?format=obj&resolution=256&wait=120", body,
                     {"Content-Type": "model/obj"}, timeout=180)
        up_dt = time.monotonic() - t
        remaining = a.reader_seconds - (time.monotonic() - t0)
        if remaining > 0:
            time.sleep(remaining)
        stop.set()
        for th in ths:
            th.join(10)
        dt = time.monotonic() - t0
        peak = srv.hwm()
    finally:
        srv.stop()
    overhead = a.overhead
    readers = [o for o in out if o]
    rates = [o[1] / o[3] / 1e3 for o in readers if o[0] == 200 and o[3] > 0]
    cut = count(o[2] for o in readers if o[2])
    dims = "x".join(map(str, meta["grid"]["dims"]))
    tab.row("slow readers", f"{a.readers} × GET data?format=npy ({dims}, holds {conversion_cost(meta) / MiB:.1f} MiB each) "
            f"read at ~{a.reader_rate / 1e3:.0f} KB/s for {a.reader_seconds:.0f} s; budget {label}",
            "readers " + count(o[0] for o in readers), dt, peak,
            f"RSS with readers {mb(rss_readers)} MiB; readers' mean rate "
            f"{statistics.mean(rates) if rates else 0:.0f} KB/s" + (f"; reader errors {cut}" if cut else "")
            + over_note(peak, budget, overhead))
    tab.row("slow readers", f"then 1 × POST {os.path.basename(bunny)} ({len(body) / 1e6:.1f} MB), resolution 256",
            up.key + (f" {up.problem}" if up.problem else ""), up_dt, peak,
            "expected 201 or 503 busy, never 408" + ("" if up.status in (201, 503) else f" — GOT {up.key}"))


def slow_class(a, tab):
    data, vid, meta = make_volume(a)
    try:
        slow_round(a, tab, data, vid, meta, a.max_memory, f"{a.max_memory / MiB:.0f} MiB")
        if not a.addr:
            # a budget the readers fill exactly: the upload has to wait for memory
            # (+1 MiB for the KiB rounding; less than the upload's 2.4 MB)
            tight = a.readers * conversion_cost(meta) + MiB
            slow_round(a, tab, data, vid, meta, tight, f"{tight / MiB:.1f} MiB = {a.readers} × that + 1 MiB")
    finally:
        if data:
            shutil.rmtree(data, ignore_errors=True)


# ---------------------------------------------------------------------------------------------
# older classes


def old_class(a, tab):
    extra = ["--header-timeout", a.header_timeout, "--body-timeout", a.body_timeout]
    srv = Server(a, extra)
    try:
        addr = srv.addr
        ht, bt = a.header_timeout, a.body_timeout

        def row(sent, res, expect):
            r, dt = res
            st = r.key + (f" {r.problem}" if r.problem else (" (bare)" if r.status else ""))
            ok = r.key in expect.split("/")
            tab.row("old", sent, st, dt, srv.hwm(), f"expected {expect}" + ("" if ok else " — MISMATCH"))

        big = b"GET /healthz HTTP/1.1\r\nHost: x\r\nX-Big: " + b"a" * (70 * 1024) + b"\r\n\r\n"
        row("head with a 70 KiB field", raw(addr, big, 15), "431")
        huge = b"GET /healthz HTTP/1.1\r\nHost: x\r\nX-Big: " + b"a" * (200 * 1024) + b"\r\n\r\n"
        row("head with a 200 KiB field", raw(addr, huge, 15), "431/closed/ConnectionResetError")
        many = b"GET /healthz HTTP/1.1\r\nHost: x\r\n" + b"".join(b"X-F%d: 1\r\n" % i for i in range(150)) + b"\r\n"
        row("head with 150 fields", raw(addr, many, 15), "431")
        row("POST voxelize declaring Content-Length 300 MB, no body",
            raw(addr, b"POST /v1/voxelize?format=obj HTTP/1.1\r\nHost: x\r\nContent-Length: 314572800\r\n\r\n", 15),
            "413")
        row("POST voxelize with Expect: 200-ok",
            raw(addr, b"POST /v1/voxelize?format=obj HTTP/1.1\r\nHost: x\r\nExpect: 200-ok\r\nContent-Length: 8\r\n\r\nv 0 0 0\n", 15),
            "417")
        notgz = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n" * 100
        row("POST voxelize, Content-Encoding: gzip, body not gzip",
            raw(addr, b"POST /v1/voxelize?format=obj HTTP/1.1\r\nHost: x\r\nContent-Encoding: gzip\r\n"
                b"Content-Length: %d\r\n\r\n" % len(notgz) + notgz, 15), "400/415/422")
        row(f"half-sent head, then nothing (--header-timeout {ht})",
            raw(addr, HALF_HEAD, ht + 15), "408/closed")
        row(f"POST voxelize, 1 KB of a 100 KB body, then nothing (--body-timeout {bt})",
            raw(addr, b"POST /v1/voxelize?format=obj HTTP/1.1\r\nHost: x\r\nContent-Length: 100000\r\n\r\n"
                + b"v 0 0 0\n" * 128, bt + 15), "408")
        drip = [(1.0, b"v 0 0 0\n" * 16)] * 40  # 128 B/s, pauses under the body timeout
        row("POST voxelize, 100 KB body dripped at 128 B/s (--min-body-rate 16384 after 10 s)",
            raw(addr, b"POST /v1/voxelize?format=obj HTTP/1.1\r\nHost: x\r\nContent-Length: 100000\r\n\r\n",
                45, drip), "408")
    finally:
        srv.stop()


# ---------------------------------------------------------------------------------------------


def ints(s):
    return [int(x) for x in s.split(",") if x]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    default_bin = "/tmp/voxd-bench" if os.path.exists("/tmp/voxd-bench") else os.path.join(ROOT, "target/release/voxd")
    ap.add_argument("--voxd", default=default_bin, help="binary to start (default %(default)s)")
    ap.add_argument("--addr", help="use the server at HOST:PORT instead of starting one per case "
                                    "(then server flags below are not applied)")
    ap.add_argument("--pid", type=int, help="with --addr: the server's pid, for its peak RSS")
    ap.add_argument("--classes", default="old,slow,memory,flood")
    ap.add_argument("--quick", action="store_true", help="a short pass (about 1.5 minutes)")
    ap.add_argument("--max-memory", type=int, default=1 << 30, help="--max-memory of started servers")
    ap.add_argument("--mesh", default=find_mesh("stanford-bunny.obj", "spot.obj"),
                    help="mesh voxelized for the large volume")
    ap.add_argument("--resolution", type=int, default=1024)
    ap.add_argument("--copies", default="1,4,16")
    ap.add_argument("--stats-copies", default="1,4,16,40")
    ap.add_argument("--bomb-budget", type=int, default=6 << 30,
                    help="a second --max-memory for the gzip bombs, large enough to admit their parse (0: skip)")
    ap.add_argument("--csg-sizes", default="100,250", help="MB")
    ap.add_argument("--flood-sizes", default="3000,10000")
    ap.add_argument("--probe-seconds", type=float, default=20)
    ap.add_argument("--ramp-limit", type=float, default=60, help="seconds the flood may take to open")
    ap.add_argument("--readers", type=int, default=11)
    ap.add_argument("--reader-rate", type=float, default=100e3, help="bytes/s per slow reader")
    ap.add_argument("--reader-seconds", type=float, default=40)
    ap.add_argument("--header-timeout", type=int, default=5, help="of the server started for 'old'")
    ap.add_argument("--body-timeout", type=int, default=3, help="of the server started for 'old'")
    ap.add_argument("--log", default=os.path.join(tempfile.gettempdir(), "voxd-hostile.log"),
                    help="servers' stderr")
    a = ap.parse_args()
    if a.quick:
        for k, v in dict(copies="1,4", stats_copies="1,4", csg_sizes="100", flood_sizes="1000",
                         probe_seconds=5, resolution=512, reader_seconds=15, bomb_budget=0).items():
            if ap.get_default(k) == getattr(a, k):
                setattr(a, k, v)
    a.copies, a.stats_copies, a.csg_sizes, a.flood_sizes = (
        ints(a.copies), ints(a.stats_copies), ints(a.csg_sizes), ints(a.flood_sizes))
    if a.addr:
        a.header_timeout, a.body_timeout = 20, 20  # the server's defaults, presumably
    elif not os.path.exists(a.voxd):
        sys.exit(f"no binary at {a.voxd} (--voxd)")
    classes = a.classes.split(",")
    t0 = time.monotonic()
    print(f"<!-- voxd hostile replay: {a.voxd if not a.addr else a.addr}, --max-memory {a.max_memory}, "
          f"{os.cpu_count()} CPUs, load {os.getloadavg()[0]:.1f}, classes {','.join(classes)} -->", flush=True)
    tab = Table()
    a.overhead = idle_baseline(a)
    for c in classes:
        t = time.monotonic()
        {"flood": flood_class, "memory": memory_class, "slow": slow_class, "old": old_class}[c](a, tab)
        print(f"<!-- {c}: {time.monotonic() - t:.0f} s, load {os.getloadavg()[0]:.1f} -->", flush=True)
    print(f"<!-- total {time.monotonic() - t0:.0f} s -->", flush=True)


if __name__ == "__main__":
    main()
