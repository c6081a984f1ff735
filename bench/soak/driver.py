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
import http.client
import json
import os
import random
import socket
import struct
import sys
import threading
import time

from soak_client import Client, Conn
from soak_meshes import load_meshes

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


def log(*a):
    print(time.strftime("%H:%M:%S"), *a, file=sys.stderr, flush=True)


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
