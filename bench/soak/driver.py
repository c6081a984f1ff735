#!/usr/bin/env python3
"""Load driver for the voxd soak test (bench/soak/run.sh starts the server and calls this).

Python 3 standard library only. Talks to one voxd on loopback for a fixed time with several
concurrent clients doing mixed traffic (uploads in every mesh format, sync and async jobs,
polling, random cancellations, downloads in every format and encoding, stats / query / normals /
preview / CSG / intersect / morphology, listing, random deletions, malformed and abandoned
requests, a few large jobs that cancellations hit while they run), and samples the server
process (RSS, open fds, threads, store size) every few seconds.

Writes into --out: samples.csv, summary.json, summary.txt, problems.log (every unexpected answer
and every 5xx, with its body), metrics-end.txt. Exit status 0 when the verdict is PASS, 1 when
FAIL (the rules are printed in summary.txt and described in docs/benchmarks.md).
"""

import argparse
import collections
import csv
import gzip
import http.client
import json
import os
import random
import socket
import struct
import sys
import threading
import time
import urllib.parse

# ---------------------------------------------------------------------------------------------
# Verdict rules (kept here, printed in the summary).
FD_SLACK = 16  # end fds <= warm fds + FD_SLACK
# end RSS <= RSS_FACTOR * the warm-up high water (VmHWM at the warm-up sample) + RSS_SLACK_MIB.
# The high water, not the RSS of that instant: glibc keeps memory freed after a large job mapped,
# so an idle RSS anywhere up to the high water is no leak, and a sample of RSS alone depends on
# where in an allocate/free cycle it falls.
RSS_FACTOR = 1.5
RSS_SLACK_MIB = 64
RULES = (
    "PASS needs: the server alive at the end; no 5xx except 503 busy (back-pressure, counted "
    "apart, like 429 queue-full); no connection error; every malformed request answered with a "
    "status it allows (4xx; a raw-socket case may also be closed unanswered, an upload we cut off "
    "is not answered); no answer outside the statuses each request allows; no bad download "
    "content; no job failing with engine-failure/internal; no canceled job later seen other than "
    f"canceled; and, after the load stops and the queue drains (idle), fds <= warm-up fds + "
    f"{FD_SLACK} and RSS <= {RSS_FACTOR} x the warm-up high water (VmHWM) + {RSS_SLACK_MIB} MiB. "
    "Warm-up = the first "
    "sample after every kind of large job has run to its end once (so the allocator has seen its "
    "high water) and not before min(60 s, 10% of the run), capped at 50% of the run."
)


MAX_VOLUMES = 40  # the clients delete volumes to keep the store near this
MAX_PENDING_PER_CLIENT = 6
HEAVY_FIRST_GAP_S = 12  # the first pass over the large jobs (during warm-up)
HEAVY_GAP_S = 30  # afterwards

# The aligned grid family: voxel size 1/32, origins a whole number of voxels from BASE.
VS = 0.03125
BASE = (-0.75, -0.8125, -0.75)


def log(*a):
    print(time.strftime("%H:%M:%S"), *a, file=sys.stderr, flush=True)


# ---------------------------------------------------------------------------------------------
# Meshes


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


# ---------------------------------------------------------------------------------------------
# Bookkeeping


class Stats:
    def __init__(self, out):
        self.lock = threading.Lock()
        self.by_route = collections.Counter()  # (method route, status) -> n
        self.bad_cases = collections.Counter()  # (case, status) -> n
        self.latency = collections.defaultdict(list)
        self.conn_errors = collections.Counter()  # (route, kind) -> n
        self.keepalive_retries = 0
        self.retry_after = collections.Counter()  # (previous request on that connection, its status)
        self.server_errors = 0  # 5xx other than 503 busy
        self.busy = 0
        self.queue_full = 0
        self.unexpected = 0
        self.bad_content = 0
        self.job_final = collections.Counter()  # state or failed:<kind>
        self.job_bad_failures = 0
        self.cancel_violations = 0
        self.cancels = collections.Counter()  # answer to DELETE /v1/jobs: canceled-queued/running, 409...
        self.heavy = []  # (t, name, outcome)
        self.findings = []  # informational observations
        self.total = 0
        self.t0 = time.monotonic()
        self.problems = open(os.path.join(out, "problems.log"), "w", buffering=1)

    def now(self):
        return time.monotonic() - self.t0

    def problem(self, kind, text):
        self.problems.write(f"[{self.now():7.1f}s] {kind}: {text}\n")

    def record(self, route, status, latency):
        with self.lock:
            self.total += 1
            self.by_route[(route, status)] += 1
            self.latency[route].append(latency)

    def count(self, attr, n=1):
        with self.lock:
            setattr(self, attr, getattr(self, attr) + n)


def problem_type(body):
    try:
        return json.loads(body).get("type", "").rsplit("/", 1)[-1]
    except Exception:
        return ""


class Shared:
    """What the clients know: stored volumes and jobs in flight."""

    def __init__(self):
        self.lock = threading.Lock()
        self.volumes = {}  # id -> {"kind", "grid", "aligned"}
        self.jobs = {}  # id -> {"kind", "grid", "aligned", "owner", "heavy"}
        self.canceled = {}  # id -> time canceled (checked again later)
        self.heavy_next = 0.0
        self.heavy_index = 0
        self.first_pass_finished = 0
        self.first_pass_done_t = None  # when every large job had run once (the warm-up)
        self.stop = threading.Event()

    def add_volume(self, vid, kind, grid, aligned):
        with self.lock:
            self.volumes[vid] = {"kind": kind, "grid": grid, "aligned": aligned}

    def pick_volume(self, rng, kind=None, aligned=None):
        with self.lock:
            c = [
                (k, v)
                for k, v in self.volumes.items()
                if (kind is None or v["kind"] == kind) and (aligned is None or v["aligned"] == aligned)
            ]
        return rng.choice(c) if c else (None, None)

    def forget_volume(self, vid):
        with self.lock:
            self.volumes.pop(vid, None)


# ---------------------------------------------------------------------------------------------
# HTTP


class Conn:
    """One client's keep-alive connection (reopened after 5 s idle or 100 requests)."""

    def __init__(self, host, port, stats):
        self.host, self.port, self.stats = host, port, stats
        self.c = None
        self.last = 0.0
        self.uses = 0
        self.prev = None  # the last request answered on this connection, and its status

    def close(self):
        if self.c is not None:
            self.c.close()
        self.c = None

    def req(self, method, path, route, body=None, headers=None, expect=(200,), timeout=120):
        """(status, headers, body) or None after a connection error. Statuses outside `expect`
        are counted and logged as unexpected."""
        hdrs = {"User-Agent": "voxd-soak"}
        hdrs.update(headers or {})
        for attempt in (0, 1):
            fresh = self.c is None or time.monotonic() - self.last > 5 or self.uses >= 100
            if fresh:
                self.close()
                self.c = http.client.HTTPConnection(self.host, self.port, timeout=timeout)
                self.uses = 0
            self.c.timeout = timeout
            if self.c.sock is not None:
                self.c.sock.settimeout(timeout)
            t = time.monotonic()
            try:
                self.c.request(method, path, body=body, headers=hdrs)
                r = self.c.getresponse()
                data = r.read()
            except (http.client.RemoteDisconnected, BrokenPipeError, ConnectionResetError) as e:
                self.close()
                if not fresh and attempt == 0:
                    # The server may close a kept-alive connection at any time; a request sent
                    # into that race is retried once on a new connection.
                    with self.stats.lock:
                        self.stats.keepalive_retries += 1
                        self.stats.retry_after[self.prev] += 1
                    continue
                return self._conn_error(method, path, route, e)
            except Exception as e:  # timeouts, refused, protocol errors
                self.close()
                return self._conn_error(method, path, route, e)
            self.last = time.monotonic()
            self.uses += 1
            lat = self.last - t
            rh = {k.lower(): v for k, v in r.getheaders()}
            self.prev = (route, r.status)
            if r.will_close:
                self.close()
            self._account(method, path, route, r.status, rh, data, lat, expect)
            return r.status, rh, data
        raise AssertionError("unreachable")

    def _conn_error(self, method, path, route, e):
        with self.stats.lock:
            self.stats.conn_errors[(route, type(e).__name__)] += 1
        self.stats.problem("connection error", f"{method} {path}: {type(e).__name__}: {e}")
        return None

    def _account(self, method, path, route, status, rh, data, lat, expect):
        st = self.stats
        st.record(route, status, lat)
        if status >= 500:
            kind = problem_type(data)
            if status == 503 and kind == "busy":
                st.count("busy")
            else:
                st.count("server_errors")
                st.problem("5xx", f"{method} {path} -> {status} {data[:600]!r}")
                return
        if status == 429:
            st.count("queue_full")
            if not rh.get("retry-after", "").isdigit():
                st.count("unexpected")
                st.problem("unexpected", f"{method} {path} -> 429 without a numeric Retry-After")
            return
        if status not in expect and not (status == 503 and problem_type(data) == "busy"):
            st.count("unexpected")
            st.problem("unexpected", f"{method} {path} -> {status} (allowed {expect}) {data[:600]!r}")


def raw_exchange(host, port, chunks, *, shut_wr=False, close_after_send=False, pause=0.0, timeout=40):
    """Sends the chunks on a new socket (pausing `pause` s after the first), then reads one
    response. Returns an int status, or 'closed' (the server closed without answering), 'reset',
    'timeout' (no answer within `timeout`), 'abandoned' (we closed first)."""
    s = socket.create_connection((host, port), timeout=timeout)
    try:
        try:
            for i, c in enumerate(chunks):
                s.sendall(c)
                if i == 0 and pause:
                    time.sleep(pause)
            if close_after_send:
                # An abrupt close (RST) mid-upload.
                s.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
                return "abandoned"
            if shut_wr:
                s.shutdown(socket.SHUT_WR)
        except (BrokenPipeError, ConnectionResetError):
            pass  # the server answered (and closed) before the whole body was sent: read it
        buf = b""
        while b"\r\n\r\n" not in buf:
            try:
                d = s.recv(65536)
            except socket.timeout:
                return "timeout"
            except ConnectionResetError:
                return int(buf[9:12]) if buf.startswith(b"HTTP/1.1 ") else "reset"
            if not d:
                return int(buf[9:12]) if buf.startswith(b"HTTP/1.1 ") else "closed"
            buf += d
        return int(buf[9:12])
    finally:
        s.close()


# ---------------------------------------------------------------------------------------------
# Clients


def grid_q(g):
    return (
        "origin=%s&voxel_size=%s&dims=%s"
        % (",".join(repr(x) for x in g["origin"]), repr(g["voxel_size"]), ",".join(str(d) for d in g["dims"]))
    )


class Client(threading.Thread):
    def __init__(self, n, args, stats, shared, small, heavy, seed):
        super().__init__(name=f"client-{n}", daemon=True)
        self.n, self.args, self.st, self.sh = n, args, stats, shared
        self.small, self.heavy = small, heavy
        self.rng = random.Random(seed)
        self.conn = Conn(args.host, args.port, stats)
        self.pending = []  # job ids this client polls

    # -- uploads ---------------------------------------------------------------------------
    def submit(self, mesh, query, *, kind="bits", aligned=False, heavy=None, wait=None, protect=False):
        q = query
        if mesh.fmt:
            q += "&format=" + mesh.fmt
        if wait is not None:
            q += f"&wait={wait}"
        if self.rng.random() < 0.3:
            q += "&name=" + urllib.parse.quote(f"soak-{self.n}-{self.rng.randrange(10**6)}")
        hdrs = {}
        if mesh.ctype:
            hdrs["Content-Type"] = mesh.ctype
        if mesh.gzip_enc:
            hdrs["Content-Encoding"] = "gzip"
        r = self.conn.req(
            "POST", "/v1/voxelize?" + q, "POST /v1/voxelize", mesh.data, hdrs, expect=(201, 202), timeout=(wait or 0) + 120
        )
        if r is None:
            return None
        status, _, body = r
        if status == 201:
            v = json.loads(body)
            self.sh.add_volume(v["id"], v["kind"], v["grid"], aligned)
            return None
        if status == 202:
            j = json.loads(body)
            with self.sh.lock:
                self.sh.jobs[j["id"]] = {"kind": kind, "grid": j["grid"], "aligned": aligned, "heavy": heavy, "protect": protect}
            self.pending.append(j["id"])
            return j["id"]
        return None

    def act_submit(self):
        if len(self.pending) >= MAX_PENDING_PER_CLIENT:
            return self.act_poll()
        mesh = self.rng.choice(self.small)
        kind = "bits"
        aligned = False
        r = self.rng.random()
        if mesh.aligned and r < 0.45:
            # The aligned family, for CSG.
            o = [b + VS * self.rng.randint(-3, 3) for b in BASE]
            d = [self.rng.randint(44, 56), self.rng.randint(56, 64), self.rng.randint(56, 64)]
            q = grid_q({"origin": o, "voxel_size": VS, "dims": d})
            q += "&method=" + self.rng.choice(["solid", "solid", "surface", "conservative", "interior"])
            aligned = True
        else:
            q = "resolution=%d" % self.rng.choice([16, 24, 32, 48, 64, 80, 96])
            m = self.rng.choice(["solid", "solid", "surface", "conservative", "interior", "density"])
            q += "&method=" + m
            if m == "density":
                kind = "density"
                q += "&density_factor=" + self.rng.choice(["2", "4"])
            if m != "surface" and self.rng.random() < 0.4:
                q += "&fill=" + self.rng.choice(["parity", "vote", "winding", "flood", "auto"])
            if self.rng.random() < 0.2:
                q += "&cubic=true"
            if self.rng.random() < 0.2:
                q += "&padding=%d" % self.rng.randint(1, 3)
        wait = self.rng.choice([None, None, 5, 30])
        self.submit(mesh, q, kind=kind, aligned=aligned, wait=wait)

    def act_heavy(self):
        with self.sh.lock:
            now = self.st.now()
            due = now >= self.sh.heavy_next
            if due:
                first_pass = self.sh.heavy_index < len(self.heavy)
                if first_pass:
                    name, mesh, q = self.heavy[self.sh.heavy_index]
                else:
                    name, mesh, q = self.rng.choice(self.heavy)
                self.sh.heavy_index += 1
                self.sh.heavy_next = now + (HEAVY_FIRST_GAP_S if first_pass else HEAVY_GAP_S)
        if not due:
            return self.act_submit()
        kind = "density" if "density" in q else "bits"
        jid = self.submit(mesh, q, kind=kind, heavy=name, protect=first_pass)
        outcome = "submitted"
        if jid and not first_pass and self.rng.random() < 0.6:
            # Cancel it after a while: queued, or running (the winding fill and the CPU engine
            # check for cancellation per block / band).
            time.sleep(self.rng.uniform(0.2, 4.0))
            outcome = "cancel -> " + self.cancel(jid)
        elif jid is None:
            outcome = "not queued"
        t_sub = round(self.st.now(), 1)
        if first_pass and jid:
            # The first pass runs each large job to its end (warm-up: the allocator's high water).
            deadline = time.monotonic() + 300
            state = "pending"
            while time.monotonic() < deadline and not self.sh.stop.is_set():
                state = self.poll(jid)
                if state != "pending":
                    break
                time.sleep(1)
            outcome = f"first run, waited for: {state} at {self.st.now():.0f} s"
        elif jid and outcome == "submitted":
            # Not canceled: see how it ends (in the background of this client's other work).
            outcome = "left to run"
        with self.st.lock:
            self.st.heavy.append((t_sub, name, outcome))
        if first_pass:
            with self.sh.lock:
                self.sh.first_pass_finished += 1
                if self.sh.first_pass_finished == len(self.heavy):
                    self.sh.first_pass_done_t = self.st.now()

    # -- jobs ------------------------------------------------------------------------------
    def poll(self, jid):
        r = self.conn.req("GET", f"/v1/jobs/{jid}", "GET /v1/jobs/{id}", expect=(200,))
        if r is None or r[0] != 200:
            return "error"
        j = json.loads(r[2])
        state = j["state"]
        if state in ("queued", "running"):
            if not 0.0 <= j.get("progress", 0.0) <= 1.0:
                self.st.count("unexpected")
                self.st.problem("unexpected", f"job {jid} progress {j.get('progress')}")
            return "pending"
        with self.sh.lock:
            info = self.sh.jobs.pop(jid, None)
            was_canceled = jid in self.sh.canceled
        if jid in self.pending:
            self.pending.remove(jid)
        if was_canceled and state != "canceled":
            self.st.count("cancel_violations")
            self.st.problem("cancel violation", f"job {jid} canceled (200) but now {state}: {r[2][:400]!r}")
        if info is None:
            return state  # someone else saw it finish
        if state == "succeeded":
            with self.st.lock:
                self.st.job_final["succeeded"] += 1
            self.sh.add_volume(j["volume_id"], info["kind"], j["grid"], info["aligned"])
        elif state == "failed":
            kind = (j.get("problem") or {}).get("type", "").rsplit("/", 1)[-1]
            with self.st.lock:
                self.st.job_final["failed:" + kind] += 1
            if kind in ("engine-failure", "internal", ""):
                self.st.count("job_bad_failures")
                self.st.problem("job failed", f"job {jid}: {r[2][:600]!r}")
        else:
            with self.st.lock:
                self.st.job_final[state] += 1
        return state

    def act_poll(self):
        if not self.pending:
            return self.act_get_volume()
        self.poll(self.rng.choice(self.pending))

    def cancel(self, jid):
        r = self.conn.req("DELETE", f"/v1/jobs/{jid}", "DELETE /v1/jobs/{id}", expect=(200, 409))
        if r is None:
            return "error"
        status, _, body = r
        if status == 200:
            j = json.loads(body)
            with self.sh.lock:
                self.sh.canceled[jid] = time.monotonic()
                self.sh.jobs.pop(jid, None)
            if j["state"] != "canceled":
                self.st.count("unexpected")
                self.st.problem("unexpected", f"DELETE job {jid} -> 200 but state {j['state']}")
            prog = j.get("progress") or 0.0
            what = "canceled (was running)" if prog > 0 or j["timings"].get("running_s") is not None else "canceled (was queued)"
            with self.st.lock:
                self.st.cancels[what] += 1
                self.st.job_final["canceled"] += 1
            if jid in self.pending:
                self.pending.remove(jid)
            return what
        if status == 409:
            with self.st.lock:
                self.st.cancels["409 already finished"] += 1
            return "409 already finished"
        return str(status)

    def act_cancel(self):
        with self.sh.lock:
            # Not the warm-up's first run of each large job: that one runs to its end.
            ids = [k for k, v in self.sh.jobs.items() if not v.get("protect")]
        if not ids:
            return self.act_submit()
        self.cancel(self.rng.choice(ids))

    def act_recheck_canceled(self):
        """A job canceled a while ago must still read canceled."""
        with self.sh.lock:
            old = [k for k, t in self.sh.canceled.items() if time.monotonic() - t > 3]
            jid = self.rng.choice(old) if old else None
            if jid:
                del self.sh.canceled[jid]
        if jid is None:
            return self.act_list()
        r = self.conn.req("GET", f"/v1/jobs/{jid}", "GET /v1/jobs/{id}", expect=(200,))
        if r and r[0] == 200:
            s = json.loads(r[2])["state"]
            if s != "canceled":
                self.st.count("cancel_violations")
                self.st.problem("cancel violation", f"job {jid} canceled, later {s}: {r[2][:400]!r}")

    # -- volumes ---------------------------------------------------------------------------
    def act_list(self):
        after = None
        seen = []
        for _ in range(self.rng.randint(1, 6)):
            q = "limit=%d" % self.rng.choice([1, 5, 10, 50, 100])
            if after:
                q += "&after=" + after
            r = self.conn.req("GET", "/v1/volumes?" + q, "GET /v1/volumes", expect=(200,))
            if r is None or r[0] != 200:
                return
            page = json.loads(r[2])
            ids = [v["id"] for v in page["volumes"]]
            if ids != sorted(ids) or (after and ids and ids[0] <= after):
                self.st.count("unexpected")
                self.st.problem("unexpected", f"listing not in id order after {after}: {ids[:5]}")
            seen += ids
            if not page["next"]:
                break
            after = ids[-1]
        # Volumes stored by abandoned requests are not in the shared pool: delete strays when
        # the store holds too many.
        with self.sh.lock:
            known = set(self.sh.volumes) | {j for j in self.sh.jobs}
            n = len(self.sh.volumes)
        if n > MAX_VOLUMES // 2:
            for vid in [v for v in seen if v not in known][:5]:
                self.conn.req("DELETE", f"/v1/volumes/{vid}", "DELETE /v1/volumes/{id}", expect=(204, 404))

    def act_get_volume(self):
        vid, _ = self.sh.pick_volume(self.rng)
        if vid is None:
            return self.act_submit()
        self.conn.req("GET", f"/v1/volumes/{vid}", "GET /v1/volumes/{id}", expect=(200, 404))

    def act_data(self):
        vid, v = self.sh.pick_volume(self.rng)
        if vid is None:
            return self.act_submit()
        fmt = self.rng.choice(["vxl", "binvox", "npy", "raw", None])
        enc = self.rng.choice([None, "gzip", "zstd", "gzip, zstd", "br", "identity"])
        path = f"/v1/volumes/{vid}/data" + (f"?format={fmt}" if fmt else "")
        hdrs = {"Accept-Encoding": enc} if enc else {}
        ok = (200, 400, 404) if fmt == "binvox" and v["kind"] == "density" else (200, 404)
        r = self.conn.req("GET", path, "GET /v1/volumes/{id}/data", headers=hdrs, expect=ok)
        if r is None or r[0] != 200:
            return
        status, rh, body = r
        ce = rh.get("content-encoding", "")
        err = None
        if ce and (not enc or ce not in enc):
            err = f"content-encoding {ce} not asked for ({enc})"
        elif ce == "gzip":
            try:
                body = gzip.decompress(body)
            except Exception as e:
                err = f"bad gzip: {e}"
        elif ce == "zstd":
            if body[:4] != b"\x28\xb5\x2f\xfd":
                err = "bad zstd magic"
            body = None  # no zstd in the standard library: the magic is all we check
        elif ce:
            err = f"unknown content-encoding {ce}"
        if err is None and body is not None:
            x, y, z = v["grid"]["dims"]
            magic = {"vxl": b"\x89VXL\r\n\x1a\n", None: b"\x89VXL\r\n\x1a\n", "npy": b"\x93NUMPY", "binvox": b"#binvox"}
            if fmt == "raw":
                if len(body) != x * y * z:
                    err = f"raw length {len(body)} != {x * y * z}"
            elif not body.startswith(magic[fmt]):
                err = f"bad {fmt} magic {body[:10]!r}"
            elif fmt == "npy" and f"({x}, {y}, {z})".encode() not in body[:200]:
                err = f"npy shape not ({x}, {y}, {z}): {body[:120]!r}"
        if err:
            self.st.count("bad_content")
            self.st.problem("bad content", f"GET {path} (Accept-Encoding {enc}): {err}")
            return
        etag = rh.get("etag")
        if etag and self.rng.random() < 0.3:
            h = dict(hdrs)
            h["If-None-Match"] = etag
            self.conn.req("GET", path, "GET /v1/volumes/{id}/data (If-None-Match)", headers=h, expect=(304, 404))

    def act_stats(self):
        vid, v = self.sh.pick_volume(self.rng)
        if vid is None:
            return self.act_submit()
        ok = (200, 404, 422)  # 422 wrong-volume-kind for density
        self.conn.req("GET", f"/v1/volumes/{vid}/stats", "GET /v1/volumes/{id}/stats", expect=ok)

    def rand_point(self, g, margin=0.2):
        return [
            o + s * self.rng.uniform(-margin, 1 + margin)
            for o, s in zip(g["origin"], [d * g["voxel_size"] for d in g["dims"]])
        ]

    def act_query(self):
        vid, v = self.sh.pick_volume(self.rng)
        if vid is None:
            return self.act_submit()
        g = v["grid"]
        pts = [self.rand_point(g) for _ in range(self.rng.randint(1, 200))]  # none and no rays: 400
        rays = []
        for _ in range(self.rng.randint(0, 50)):
            d = [self.rng.uniform(-1, 1) for _ in range(3)]
            if self.rng.random() < 0.02:
                d = [0, 0, 0]  # a degenerate direction: allowed 400
            rays.append({"origin": self.rand_point(g, 0.5), "direction": d})
        body = json.dumps({"points": pts, "rays": rays}).encode()
        self.conn.req(
            "POST", f"/v1/volumes/{vid}/query", "POST /v1/volumes/{id}/query", body,
            {"Content-Type": "application/json"}, expect=(200, 404) if [0, 0, 0] not in [r["direction"] for r in rays] else (200, 400, 404),
        )

    def act_normals(self):
        vid, v = self.sh.pick_volume(self.rng)
        if vid is None:
            return self.act_submit()
        pts = ";".join(",".join("%.5g" % c for c in self.rand_point(v["grid"])) for _ in range(self.rng.randint(1, 20)))
        self.conn.req("GET", f"/v1/volumes/{vid}/normals?points=" + urllib.parse.quote(pts), "GET /v1/volumes/{id}/normals", expect=(200, 404))

    def act_preview(self):
        vid, v = self.sh.pick_volume(self.rng)
        if vid is None:
            return self.act_submit()
        axis = self.rng.choice("xyz")
        q = f"axis={axis}"
        if self.rng.random() < 0.5:
            q += "&slice=%d" % self.rng.randrange(v["grid"]["dims"]["xyz".index(axis)])
        else:
            q += "&projection=" + self.rng.choice(["max", "sum"])
        r = self.conn.req("GET", f"/v1/volumes/{vid}/preview.png?{q}", "GET /v1/volumes/{id}/preview.png", expect=(200, 404))
        if r and r[0] == 200 and not r[2].startswith(b"\x89PNG\r\n\x1a\n"):
            self.st.count("bad_content")
            self.st.problem("bad content", f"preview of {vid} is not a PNG")

    def act_csg(self):
        ids = []
        for _ in range(self.rng.randint(2, 4)):
            vid, _ = self.sh.pick_volume(self.rng, kind="bits", aligned=self.rng.random() < 0.9 or None)
            if vid:
                ids.append(vid)
        if len(ids) < 2:
            return self.act_submit()
        ops = ["union", "intersection", "difference", "xor"]
        expr = {"op": self.rng.choice(ops), "operands": ids[:2]}
        if len(ids) > 2:
            expr = {"op": self.rng.choice(ops), "operands": [expr] + ids[2:]}
        r = self.conn.req(
            "POST", "/v1/volumes/csg?name=soak-csg", "POST /v1/volumes/csg", json.dumps(expr).encode(),
            {"Content-Type": "application/json"}, expect=(201, 404, 422),
        )
        if r and r[0] == 201:
            v = json.loads(r[2])
            with self.sh.lock:
                aligned = all(self.sh.volumes.get(i, {}).get("aligned") for i in ids)
            self.sh.add_volume(v["id"], "bits", v["grid"], aligned)

    def act_intersect(self):
        a, _ = self.sh.pick_volume(self.rng, kind="bits", aligned=True)
        b, _ = self.sh.pick_volume(self.rng, kind="bits")
        if not a or not b:
            return self.act_submit()
        self.conn.req(
            "POST", "/v1/volumes/intersect", "POST /v1/volumes/intersect", json.dumps({"a": a, "b": b}).encode(),
            {"Content-Type": "application/json"}, expect=(200, 404, 422),
        )

    def act_morph(self):
        vid, v = self.sh.pick_volume(self.rng, kind="bits")
        if vid is None:
            return self.act_submit()
        body = {"op": self.rng.choice(["dilate", "erode", "open", "close"]), "radius": self.rng.randint(0, 3)}
        if self.rng.random() < 0.7:
            body["kernel"] = self.rng.choice(["cube", "cross", "sphere"])
        if self.rng.random() < 0.3:
            body["grow"] = True
        r = self.conn.req(
            "POST", f"/v1/volumes/{vid}/morphology", "POST /v1/volumes/{id}/morphology", json.dumps(body).encode(),
            {"Content-Type": "application/json"}, expect=(201, 404),
        )
        if r and r[0] == 201:
            n = json.loads(r[2])
            self.sh.add_volume(n["id"], "bits", n["grid"], v["aligned"])

    def act_delete(self):
        with self.sh.lock:
            n = len(self.sh.volumes)
        for _ in range(3 if n > MAX_VOLUMES else 1):
            vid, _ = self.sh.pick_volume(self.rng)
            if vid is None:
                return
            self.sh.forget_volume(vid)
            self.conn.req("DELETE", f"/v1/volumes/{vid}", "DELETE /v1/volumes/{id}", expect=(204, 404))
            if self.rng.random() < 0.2:
                # Gone for good: reads say 404.
                self.conn.req("GET", f"/v1/volumes/{vid}/data", "GET /v1/volumes/{id}/data", expect=(404,))

    def act_health(self):
        p = self.rng.choice(["/healthz", "/readyz", "/metrics", "/openapi.yaml"])
        self.conn.req("GET", p, "GET " + p, expect=(200,))

    def act_abandon(self):
        """A request whose client goes away before the answer: a voxelize with wait, or a
        morphology / stats (synchronous operations stop when their client disconnects)."""
        vid, _ = self.sh.pick_volume(self.rng, kind="bits")
        if vid and self.rng.random() < 0.6:
            body = json.dumps({"op": "close", "radius": self.rng.randint(4, 12), "kernel": "sphere", "grow": True}).encode()
            req = (
                f"POST /v1/volumes/{vid}/morphology HTTP/1.1\r\nHost: soak\r\nContent-Type: application/json\r\n"
                f"Content-Length: {len(body)}\r\n\r\n"
            ).encode() + body
            case = "abandon morphology"
        else:
            m = self.small[0]
            req = (
                f"POST /v1/voxelize?resolution=64&wait=30 HTTP/1.1\r\nHost: soak\r\nContent-Type: model/obj\r\n"
                f"Content-Length: {len(m.data)}\r\n\r\n"
            ).encode() + m.data
            case = "abandon voxelize wait=30"
        s = socket.create_connection((self.args.host, self.args.port), timeout=30)
        try:
            s.sendall(req)
            time.sleep(self.rng.uniform(0.0, 0.3))
        except OSError as e:
            with self.st.lock:
                self.st.conn_errors[(case, type(e).__name__)] += 1
        finally:
            s.close()
        with self.st.lock:
            self.st.bad_cases[(case, "abandoned")] += 1

    def act_malformed(self):
        bad_case(self.rng, self.st, self.sh, self.conn, self.small)

    # -- main loop -------------------------------------------------------------------------
    def run(self):
        acts = [
            (self.act_submit, 26), (self.act_poll, 14), (self.act_cancel, 6), (self.act_recheck_canceled, 2),
            (self.act_list, 5), (self.act_get_volume, 5), (self.act_data, 14), (self.act_stats, 5),
            (self.act_query, 5), (self.act_normals, 3), (self.act_preview, 4), (self.act_csg, 5),
            (self.act_intersect, 3), (self.act_morph, 4), (self.act_delete, 6), (self.act_health, 3),
            (self.act_malformed, 5), (self.act_abandon, 1), (self.act_heavy, 2 if self.heavy else 0),
        ]
        fns = [a for a, _ in acts]
        weights = [w for _, w in acts]
        while not self.sh.stop.is_set():
            with self.sh.lock:
                n = len(self.sh.volumes)
            f = self.act_delete if n > MAX_VOLUMES and self.rng.random() < 0.5 else self.rng.choices(fns, weights)[0]
            try:
                f()
            except Exception as e:  # a driver bug must not end the soak silently
                self.st.count("unexpected")
                self.st.problem("driver exception", f"{f.__name__}: {type(e).__name__}: {e}")
            time.sleep(self.rng.uniform(0, 0.05))
        self.conn.close()


# ---------------------------------------------------------------------------------------------
# Malformed requests (each must be answered 4xx)

EXTERNAL_GLTF = json.dumps(
    {
        "asset": {"version": "2.0"},
        "buffers": [{"uri": "../../etc/passwd", "byteLength": 36}],
        "bufferViews": [{"buffer": 0, "byteLength": 36}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "max": [1, 1, 1], "min": [0, 0, 0]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "nodes": [{"mesh": 0}],
        "scenes": [{"nodes": [0]}],
        "scene": 0,
    }
).encode()


def bad_case(rng, st, sh, conn, small):
    spot = small[0].data
    cases = [
        ("garbage mesh bytes", "POST", "/v1/voxelize?resolution=16", os.urandom(rng.randint(1, 4096)), {"Content-Type": "model/obj"}, (400, 415, 422)),
        ("garbage, no content type", "POST", "/v1/voxelize?resolution=16", os.urandom(2000), {}, (400, 415, 422)),
        ("truncated binary STL", "POST", "/v1/voxelize?resolution=16", small[2].data[: rng.randint(84, len(small[2].data) - 1)], {"Content-Type": "model/stl"}, (422,)),
        ("truncated GLB", "POST", "/v1/voxelize?resolution=16", small[7].data[: rng.randint(20, len(small[7].data) - 1)], {"Content-Type": "model/gltf-binary"}, (422,)),
        ("gzip header, not gzip", "POST", "/v1/voxelize?resolution=16", spot[:5000], {"Content-Type": "model/obj", "Content-Encoding": "gzip"}, (400, 422)),
        ("Content-Encoding br", "POST", "/v1/voxelize?resolution=16", spot, {"Content-Type": "model/obj", "Content-Encoding": "br"}, (415, 400)),
        ("glTF external buffer", "POST", "/v1/voxelize?resolution=16", EXTERNAL_GLTF, {"Content-Type": "model/gltf+json"}, (422,)),
        ("empty body", "POST", "/v1/voxelize?resolution=16", b"", {"Content-Type": "model/obj"}, (400, 422)),
        ("resolution=0", "POST", "/v1/voxelize?resolution=0", spot, {"Content-Type": "model/obj"}, (400,)),
        ("resolution=abc", "POST", "/v1/voxelize?resolution=abc", spot, {"Content-Type": "model/obj"}, (400,)),
        ("unknown parameter", "POST", "/v1/voxelize?resolution=16&bogus=1", spot, {"Content-Type": "model/obj"}, (400,)),
        ("method=bogus", "POST", "/v1/voxelize?method=bogus", spot, {"Content-Type": "model/obj"}, (400,)),
        ("fill=nope", "POST", "/v1/voxelize?fill=nope&resolution=16", spot, {"Content-Type": "model/obj"}, (400,)),
        ("wait=1000", "POST", "/v1/voxelize?wait=1000&resolution=16", spot, {"Content-Type": "model/obj"}, (400,)),
        ("density_factor=3", "POST", "/v1/voxelize?method=density&density_factor=3", spot, {"Content-Type": "model/obj"}, (400,)),
        ("grid too large", "POST", "/v1/voxelize?resolution=99999", spot, {"Content-Type": "model/obj"}, (422,)),
        ("max_voxels=10", "POST", "/v1/voxelize?resolution=64&max_voxels=10", spot, {"Content-Type": "model/obj"}, (422,)),
        ("half an explicit grid", "POST", "/v1/voxelize?origin=0,0,0&dims=4,4,4", spot, {"Content-Type": "model/obj"}, (400,)),
        ("format=xyz", "POST", "/v1/voxelize?format=xyz", spot, {}, (400, 415)),
        ("content type text/html", "POST", "/v1/voxelize?resolution=16", b"<html></html>", {"Content-Type": "text/html"}, (415, 422)),
        ("csg: not json", "POST", "/v1/volumes/csg", b"{op: union", {"Content-Type": "application/json"}, (400,)),
        ("csg: bad op", "POST", "/v1/volumes/csg", b'{"op":"nand","operands":["a","b"]}', {"Content-Type": "application/json"}, (400, 422)),
        ("csg: unknown ids", "POST", "/v1/volumes/csg", b'{"op":"union","operands":["0000000000000000","1111111111111111"]}', {"Content-Type": "application/json"}, (404,)),
        ("intersect: missing b", "POST", "/v1/volumes/intersect", b'{"a":"x"}', {"Content-Type": "application/json"}, (400, 422)),
        ("query: not json", "POST", "/v1/volumes/0000000000000000/query", b"[1,2", {"Content-Type": "application/json"}, (400, 404)),
        ("morphology: radius 999", "POST", "/v1/volumes/0000000000000000/morphology", b'{"op":"dilate","radius":999}', {"Content-Type": "application/json"}, (400, 404, 422)),
        ("job: unknown id", "GET", "/v1/jobs/doesnotexist", None, {}, (404,)),
        ("job: cancel unknown", "DELETE", "/v1/jobs/doesnotexist", None, {}, (404,)),
        ("volume: path traversal id", "GET", "/v1/volumes/..%2F..%2Fetc%2Fpasswd/data", None, {}, (400, 404)),
        ("volume: delete unknown", "DELETE", "/v1/volumes/0000000000000000", None, {}, (404,)),
        ("list: limit=0", "GET", "/v1/volumes?limit=0", None, {}, (400,)),
        ("list: limit=5000", "GET", "/v1/volumes?limit=5000", None, {}, (400,)),
        ("data: format=obj", "GET", "/v1/volumes/0000000000000000/data?format=obj", None, {}, (400, 404)),
        ("unknown route", "GET", "/v2/nothing", None, {}, (404,)),
        ("wrong method", "PUT", "/v1/volumes", b"x", {}, (405,)),
    ]
    # Some cases on a real volume, where the answer cannot be a 404 of the id.
    with_vol = []
    v, _ = sh.pick_volume(rng)
    if v:
        with_vol = [
            ("preview: slice out of range", "GET", f"/v1/volumes/{v}/preview.png?axis=z&slice=100000", None, {}, (400, 404, 422)),
            ("preview: slice and projection", "GET", f"/v1/volumes/{v}/preview.png?slice=1&projection=max", None, {}, (400, 404)),
            ("normals: bad points", "GET", f"/v1/volumes/{v}/normals?points=1,2", None, {}, (400, 404)),
            ("query: 3 numbers as a ray", "POST", f"/v1/volumes/{v}/query", b'{"rays":[{"origin":[0,0]}]}', {"Content-Type": "application/json"}, (400, 404, 422)),
            ("morphology: bad kernel", "POST", f"/v1/volumes/{v}/morphology", b'{"op":"dilate","radius":1,"kernel":"star"}', {"Content-Type": "application/json"}, (400, 404, 422)),
        ]
    name, method, path, body, hdrs, ok = rng.choice(cases + with_vol)
    r = conn.req(method, path, "(malformed requests)", body, hdrs, expect=ok)
    with st.lock:
        st.bad_cases[(name, r[0] if r else "conn-error")] += 1


class Misbehaver(threading.Thread):
    """Raw-socket clients: over-limit Content-Length, truncated bodies, uploads cut off mid-way,
    bodies that stall, headers that never end, idle connections, huge headers."""

    def __init__(self, args, stats, shared, small, seed):
        super().__init__(name="misbehaver", daemon=True)
        self.args, self.st, self.sh, self.small = args, stats, shared, small
        self.rng = random.Random(seed)
        self.slow = []

    def case(self, name, outcome, ok, t0):
        self.st.record("(raw-socket clients)", outcome, time.monotonic() - t0)
        with self.st.lock:
            self.st.bad_cases[(name, outcome)] += 1
        if outcome not in ok:
            self.st.count("unexpected")
            self.st.problem("unexpected", f"{name} -> {outcome} (allowed {ok})")
        if isinstance(outcome, int) and outcome >= 500 and outcome != 503:
            self.st.count("server_errors")
            self.st.problem("5xx", f"{name} -> {outcome}")

    def head(self, length, ctype="model/obj", extra=""):
        return (
            f"POST /v1/voxelize?resolution=32 HTTP/1.1\r\nHost: soak\r\nContent-Type: {ctype}\r\n"
            f"Content-Length: {length}\r\n{extra}\r\n"
        ).encode()

    def quick(self):
        h, p = self.args.host, self.args.port
        spot = self.small[0].data
        t = time.monotonic()
        k = self.rng.randrange(5)
        if k == 0:
            self.case("Content-Length over the body limit", raw_exchange(h, p, [self.head(300 << 20)]), (413,), t)
        elif k == 1:
            n = self.rng.randint(1, len(spot) - 1)
            self.case("truncated body (half-close)", raw_exchange(h, p, [self.head(len(spot)), spot[:n]], shut_wr=True), (400, 408, 422, "closed"), t)
        elif k == 2:
            n = self.rng.randint(0, len(spot) - 1)
            self.case("disconnect mid-upload", raw_exchange(h, p, [self.head(len(spot)), spot[:n]], close_after_send=True), ("abandoned",), t)
        elif k == 3:
            big = "X-Pad: " + "a" * (70 << 10) + "\r\n"
            self.case("70 KiB of headers", raw_exchange(h, p, [self.head(len(spot), extra=big), spot]), (431, "closed", "reset"), t)
        else:
            self.case("not HTTP", raw_exchange(h, p, [b"\x16\x03\x01\x02\x00 hello\r\n\r\n"]), (400, "closed", "reset"), t)

    def slow_case(self):
        h, p = self.args.host, self.args.port
        k = self.rng.randrange(3)
        t = time.monotonic()
        if k == 0:
            # The body stalls for longer than the 20 s body pause limit.
            out = raw_exchange(h, p, [self.head(len(self.small[0].data)), self.small[0].data[:1000]], timeout=45)
            self.case("body stalls > 20 s", out, (408,), t)
        elif k == 1:
            # A head that never ends (slowloris): closed after the 20 s header timeout.
            out = raw_exchange(h, p, [b"POST /v1/voxelize HTTP/1.1\r\nHost: soak\r\n"], timeout=45)
            self.case("head never ends", out, (408, "closed", "reset"), t)
        else:
            # Connected, never sends a byte.
            out = raw_exchange(h, p, [b""], timeout=45)
            self.case("idle connection, no bytes", out, (408, "closed", "reset"), t)
        with self.st.lock:
            self.st.latency[f"slow: {['body stalls', 'head never ends', 'idle connection'][k]}"].append(time.monotonic() - t)

    def run(self):
        next_slow = 20.0
        while not self.sh.stop.is_set():
            self.slow = [s for s in self.slow if s.is_alive()]
            if self.st.now() >= next_slow and len(self.slow) < 3:
                th = threading.Thread(target=self.guard(self.slow_case), daemon=True)
                th.start()
                self.slow.append(th)
                next_slow = self.st.now() + 15
            self.guard(self.quick)()
            time.sleep(self.rng.uniform(0.2, 0.6))
        for s in self.slow:
            s.join(60)

    def guard(self, f):
        def g():
            try:
                f()
            except Exception as e:
                with self.st.lock:
                    self.st.conn_errors[(f"misbehaver {f.__name__}", type(e).__name__)] += 1
                self.st.problem("misbehaver", f"{f.__name__}: {type(e).__name__}: {e}")

        return g


# ---------------------------------------------------------------------------------------------
# Sampling the server process


def proc_sample(pid, data_dir):
    try:
        with open(f"/proc/{pid}/status") as f:
            st = dict(line.split(":", 1) for line in f if ":" in line)
        rss = int(st["VmRSS"].split()[0])
        hwm = int(st["VmHWM"].split()[0])
        threads = int(st["Threads"])
        fds = len(os.listdir(f"/proc/{pid}/fd"))
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        cpu_s = (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")  # utime + stime
        with open("/proc/loadavg") as f:
            load1 = float(f.read().split()[0])
    except (FileNotFoundError, ProcessLookupError, KeyError):
        return None
    size = {"volumes": 0, "jobs": 0}
    files = {"volumes": 0, "jobs": 0}
    for sub in ("volumes", "jobs"):
        try:
            for e in os.scandir(os.path.join(data_dir, sub)):
                try:
                    size[sub] += e.stat().st_size
                    files[sub] += 1
                except FileNotFoundError:
                    pass
        except FileNotFoundError:
            pass
    return {"rss_kib": rss, "hwm_kib": hwm, "threads": threads, "fds": fds, "cpu_s": round(cpu_s, 1), "loadavg1": load1, "volumes_bytes": size["volumes"],
            "volume_files": files["volumes"], "jobs_bytes": size["jobs"], "job_files": files["jobs"]}


class Sampler(threading.Thread):
    FIELDS = ["t_s", "phase", "rss_kib", "hwm_kib", "fds", "threads", "cpu_s", "loadavg1", "volumes_bytes", "volume_files", "jobs_bytes", "job_files",
              "queue_depth", "running", "stored_bytes", "requests", "server_5xx", "busy_503", "queue_full_429",
              "conn_errors", "unexpected", "volumes_known"]

    def __init__(self, args, stats, shared, out):
        super().__init__(name="sampler", daemon=True)
        self.args, self.st, self.sh = args, stats, shared
        self.rows = []
        self.phase = "load"
        self.dead = False
        self.f = open(os.path.join(out, "samples.csv"), "w", newline="")
        self.w = csv.DictWriter(self.f, self.FIELDS)
        self.w.writeheader()
        self.stop_ev = threading.Event()

    def readyz(self):
        try:
            c = http.client.HTTPConnection(self.args.host, self.args.port, timeout=10)
            c.request("GET", "/readyz")
            r = c.getresponse()
            d = json.loads(r.read())
            c.close()
            return d
        except Exception:
            return {}

    def sample(self):
        s = proc_sample(self.args.pid, self.args.data_dir)
        if s is None:
            self.dead = True
            return None
        rz = self.readyz()
        with self.st.lock:
            row = dict(
                t_s=round(self.st.now(), 1), phase=self.phase, **s,
                queue_depth=rz.get("queue_depth", ""), running=rz.get("running", ""), stored_bytes=rz.get("stored_bytes", ""),
                requests=self.st.total, server_5xx=self.st.server_errors, busy_503=self.st.busy,
                queue_full_429=self.st.queue_full, conn_errors=sum(self.st.conn_errors.values()),
                unexpected=self.st.unexpected, volumes_known=len(self.sh.volumes),
            )
        self.rows.append(row)
        self.w.writerow(row)
        self.f.flush()
        return row

    def run(self):
        while not self.stop_ev.is_set():
            if self.sample() is None:
                log("the server process is gone")
                self.sh.stop.set()
                return
            self.stop_ev.wait(self.args.interval)


# ---------------------------------------------------------------------------------------------


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--host", default="127.0.0.1")
    ap.add_argument("--port", type=int, required=True)
    ap.add_argument("--pid", type=int, required=True)
    ap.add_argument("--data-dir", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--duration", type=float, default=600)
    ap.add_argument("--clients", type=int, default=6)
    ap.add_argument("--interval", type=float, default=5)
    ap.add_argument("--repo", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
    ap.add_argument("--shared-meshes", default=None)
    ap.add_argument("--seed", type=int, default=None)
    ap.add_argument("--no-large-jobs", action="store_true", help="leave out the large jobs (to tell their memory apart)")
    args = ap.parse_args()
    assert args.host in ("127.0.0.1", "localhost", "::1"), "loopback only"
    seed = args.seed if args.seed is not None else random.randrange(1 << 30)
    shared_dir = args.shared_meshes or os.path.join(args.repo, "..", "shared", "meshes")
    small, heavy, have_shared = load_meshes(args.repo, shared_dir)
    if args.no_large_jobs:
        heavy = []
    os.makedirs(args.out, exist_ok=True)
    st = Stats(args.out)
    sh = Shared()
    log(f"seed {seed}; {args.clients} clients + 1 raw-socket client for {args.duration:.0f} s; "
        f"{len(small)} small meshes, {len(heavy)} large jobs ({'shared meshes' if have_shared else 'tests/data only'})")

    sampler = Sampler(args, st, sh, args.out)
    sampler.start()
    clients = [Client(i, args, st, sh, small, heavy, seed + i) for i in range(args.clients)]
    mis = Misbehaver(args, st, sh, small, seed + 1000)
    for c in clients + [mis]:
        c.start()
    end = time.monotonic() + args.duration
    last = 0
    while time.monotonic() < end and not sh.stop.is_set():
        time.sleep(1)
        if st.now() - last >= 60:
            last = st.now()
            r = sampler.rows[-1] if sampler.rows else {}
            log(f"t={st.now():.0f}s requests={st.total} rss={r.get('rss_kib', 0) // 1024} MiB fds={r.get('fds')} "
                f"threads={r.get('threads')} 5xx={st.server_errors} unexpected={st.unexpected} conn_errors={sum(st.conn_errors.values())}")
    load_end = st.now()
    sh.stop.set()
    join_by = time.monotonic() + 240  # a poll or a download in flight finishes first
    for c in clients + [mis]:
        c.join(max(0.1, join_by - time.monotonic()))
    stuck = [c.name for c in clients + [mis] if c.is_alive()]

    # Drain: cancel what is still queued or running, wait until the queue is empty, let idle
    # keep-alive connections close, then take the end samples.
    sampler.phase = "drain"
    tail = Conn(args.host, args.port, st)
    with sh.lock:
        left = list(sh.jobs)
    for jid in left:
        tail.req("DELETE", f"/v1/jobs/{jid}", "DELETE /v1/jobs/{id}", expect=(200, 409))
    tail.close()
    t = time.monotonic()
    while time.monotonic() - t < 120 and not sampler.dead:
        rz = sampler.readyz()
        if rz.get("queue_depth") == 0 and rz.get("running") == 0:
            break
        time.sleep(1)
    time.sleep(25)  # > the 20 s header timeout: every idle connection is closed by now
    sampler.phase = "idle"
    sampler.stop_ev.set()
    sampler.join(30)
    ends = []
    for _ in range(3):
        e = sampler.sample()
        if e is None:
            break
        ends.append(e)
        time.sleep(2)
    try:
        c = http.client.HTTPConnection(args.host, args.port, timeout=10)
        c.request("GET", "/metrics")
        with open(os.path.join(args.out, "metrics-end.txt"), "wb") as f:
            f.write(c.getresponse().read())
        c.close()
    except Exception as e:
        log(f"could not fetch /metrics at the end: {e}")

    rows = sampler.rows
    load_rows = [r for r in rows if r["phase"] == "load"]
    # Warm-up: the first sample after the first pass over the large jobs, but no later than 20%
    # of the run (short runs), and not before 60 s (or 10% of the run, whichever is less).
    warm_after = min(60, args.duration * 0.1)
    if sh.first_pass_done_t is not None:
        warm_after = max(warm_after, sh.first_pass_done_t)
    else:
        warm_after = max(warm_after, args.duration * 0.2)
    warm_after = min(warm_after, args.duration * 0.5)
    warm = next((r for r in load_rows if r["t_s"] >= warm_after), load_rows[-1] if load_rows else None)
    end_row = ends[-1] if ends else None
    peak = max(rows, key=lambda r: r["rss_kib"]) if rows else None
    peak_fds = max(rows, key=lambda r: r["fds"]) if rows else None
    steady = [r for r in load_rows if warm and r["t_s"] >= warm["t_s"]]
    slope = None
    if len(steady) >= 3:
        xs = [r["t_s"] for r in steady]
        ys = [r["rss_kib"] / 1024 for r in steady]
        mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
        den = sum((x - mx) ** 2 for x in xs)
        slope = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / den * 60 if den else None

    fails = []
    if sampler.dead or not end_row:
        fails.append("the server process died")
    if stuck:
        fails.append(f"client threads did not stop: {stuck}")
    if st.server_errors:
        fails.append(f"{st.server_errors} 5xx answers (not 503 busy)")
    if st.conn_errors:
        fails.append(f"{sum(st.conn_errors.values())} connection errors")
    if st.unexpected:
        fails.append(f"{st.unexpected} answers outside the allowed statuses")
    if st.bad_content:
        fails.append(f"{st.bad_content} bad downloads")
    if st.job_bad_failures:
        fails.append(f"{st.job_bad_failures} jobs failed with engine-failure/internal")
    if st.cancel_violations:
        fails.append(f"{st.cancel_violations} canceled jobs later not canceled")
    if warm and end_row:
        if end_row["fds"] > warm["fds"] + FD_SLACK:
            fails.append(f"fds {end_row['fds']} at the end > warm-up {warm['fds']} + {FD_SLACK}")
        lim = RSS_FACTOR * warm["hwm_kib"] + RSS_SLACK_MIB * 1024
        if end_row["rss_kib"] > lim:
            fails.append(f"RSS {end_row['rss_kib'] // 1024} MiB at the end > {lim / 1024:.0f} MiB")
    verdict = "PASS" if not fails else "FAIL"

    def mib(r, k="rss_kib"):
        return f"{r[k] / 1024:.1f} MiB" if r else "-"

    lines = [
        f"voxd soak: {args.duration:.0f} s of load, {args.clients} clients + 1 raw-socket client, seed {seed}",
        f"load ran {load_end:.0f} s; {st.total} requests ({st.total / max(load_end, 1):.1f}/s); samples every {args.interval:.0f} s",
        "",
        f"RSS   start {mib(rows[0]) if rows else '-'}, warm-up (t={warm['t_s'] if warm else '-'} s) {mib(warm)} "
        f"(high water so far {mib(warm, 'hwm_kib')}), "
        f"peak {mib(peak)} (t={peak['t_s'] if peak else '-'} s), end (idle) {mib(end_row)}, "
        f"kernel high-water VmHWM {mib(end_row, 'hwm_kib')}",
        f"      slope after warm-up under load: {slope:+.2f} MiB/min" if slope is not None else "      slope: -",
        f"fds   start {rows[0]['fds'] if rows else '-'}, warm-up {warm['fds'] if warm else '-'}, peak {peak_fds['fds'] if peak_fds else '-'} "
        f"(t={peak_fds['t_s'] if peak_fds else '-'} s), end (idle) {end_row['fds'] if end_row else '-'}",
        f"threads start {rows[0]['threads'] if rows else '-'}, peak {max(r['threads'] for r in rows) if rows else '-'}, "
        f"end {end_row['threads'] if end_row else '-'}",
        f"store at the end: {end_row['volume_files'] if end_row else '-'} files in volumes/ ({end_row['volumes_bytes'] / 1e6 if end_row else 0:.1f} MB), "
        f"{end_row['job_files'] if end_row else '-'} job records in jobs/ ({end_row['jobs_bytes'] / 1e6 if end_row else 0:.1f} MB)",
        "",
        f"5xx (not busy): {st.server_errors}; 503 busy: {st.busy}; 429 queue-full: {st.queue_full}; "
        f"unexpected statuses: {st.unexpected}; bad content: {st.bad_content}",
        f"keep-alive retries (the server had closed a kept-alive connection without saying so; retried once on a new "
        f"one): {st.keepalive_retries}, after: {dict((f'{a} {b}', n) for (a, b), n in st.retry_after.most_common(8))}",
        f"connection errors: {dict((f'{a} [{b}]', n) for (a, b), n in st.conn_errors.items()) or 0}",
        f"jobs: {dict(st.job_final)}",
        f"cancellations: {dict(st.cancels)}; canceled jobs later not canceled: {st.cancel_violations}",
        "",
        "requests by route and status (latency p50 / p99 / max, s):",
    ]
    routes = sorted({r for r, _ in st.by_route})
    for rt in routes:
        sts = ", ".join(f"{s}: {n}" for (r, s), n in sorted(st.by_route.items(), key=lambda kv: str(kv[0][1])) if r == rt)
        lat = sorted(st.latency[rt])
        q = lambda p: lat[min(len(lat) - 1, int(p * len(lat)))] if lat else 0  # noqa: E731
        lines.append(f"  {rt:55s} {sts}   ({q(0.5):.3f} / {q(0.99):.3f} / {lat[-1] if lat else 0:.3f})")
    lines.append("malformed / abandoned requests (case: outcome):")
    for (case, out), n in sorted(st.bad_cases.items(), key=lambda kv: (kv[0][0], str(kv[0][1]))):
        lines.append(f"  {case:45s} {out}: {n}")
    for k in sorted(st.latency):
        if k.startswith("slow:"):
            lat = st.latency[k]
            lines.append(f"  {k} answered/closed after {min(lat):.1f}–{max(lat):.1f} s")
    lines.append("large jobs (t, what, outcome):")
    for t, n, o in st.heavy:
        lines.append(f"  {t:7.1f}s  {n}: {o}")
    lines += ["", "rules: " + RULES, "", f"VERDICT: {verdict}"] + [f"  - {f}" for f in fails]
    text = "\n".join(lines) + "\n"
    with open(os.path.join(args.out, "summary.txt"), "w") as f:
        f.write(text)
    summary = {
        "seed": seed, "duration_s": args.duration, "clients": args.clients, "requests": st.total,
        "rss_kib": {"start": rows[0]["rss_kib"] if rows else None, "warm": warm and warm["rss_kib"],
                    "warm_t_s": warm and warm["t_s"], "warm_hwm": warm and warm["hwm_kib"], "peak": peak and peak["rss_kib"], "end": end_row and end_row["rss_kib"],
                    "hwm_end": end_row and end_row["hwm_kib"], "slope_mib_per_min": slope},
        "fds": {"start": rows[0]["fds"] if rows else None, "warm": warm and warm["fds"], "peak": peak_fds and peak_fds["fds"],
                "end": end_row and end_row["fds"]},
        "threads": {"start": rows[0]["threads"] if rows else None, "peak": max((r["threads"] for r in rows), default=None),
                    "end": end_row and end_row["threads"]},
        "by_route": [[r, s, n] for (r, s), n in sorted(st.by_route.items(), key=lambda kv: (kv[0][0], str(kv[0][1])))],
        "bad_cases": [[c, o, n] for (c, o), n in sorted(st.bad_cases.items(), key=lambda kv: (kv[0][0], str(kv[0][1])))],
        "server_5xx": st.server_errors, "busy_503": st.busy, "queue_full_429": st.queue_full, "unexpected": st.unexpected,
        "bad_content": st.bad_content, "keepalive_retries": st.keepalive_retries,
        "keepalive_retry_after": [[a, b, n] for (a, b), n in st.retry_after.items()],
        "conn_errors": [[a, b, n] for (a, b), n in st.conn_errors.items()], "jobs": dict(st.job_final),
        "cancels": dict(st.cancels), "cancel_violations": st.cancel_violations, "heavy": st.heavy,
        "verdict": verdict, "fails": fails,
    }
    with open(os.path.join(args.out, "summary.json"), "w") as f:
        json.dump(summary, f, indent=1)
    sys.stdout.write(text)
    return 0 if verdict == "PASS" else 1


if __name__ == "__main__":
    sys.exit(main())
