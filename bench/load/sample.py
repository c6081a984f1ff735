#!/usr/bin/env python3
"""Samples a running `voxd serve` every INTERVAL s into a CSV until it is stopped (SIGTERM).

Python 3 standard library only; bench/load/run.sh starts one per server. Columns: the time
(epoch s), the phase (the current content of --phase-file, written by run.sh), from `/metrics`
voxd_queue_depth, voxd_queue_running and voxd_job_duration_seconds_count (jobs finished so far),
the `/healthz` latency (a new connection each time, ms; -1 when it failed or took over 10 s), the
`/metrics` latency, and from /proc: the server's VmRSS and VmHWM (KiB), threads, open fds, its CPU
time (user + system, s) and the whole machine's busy CPU time (s, all cores, from /proc/stat);
with --probe-dir, the time of one durable 1 KiB write there (write, fsync, rename, fsync the
directory: the store's pattern; ms), to see what the disk's fsyncs cost at that moment; and the
machine's TcpExtListenOverflows counter (SYNs dropped because a listening socket's accept queue
was full: any listener on the machine, in practice the server's).
"""

import argparse
import csv
import http.client
import os
import signal
import sys
import time

TICK = os.sysconf("SC_CLK_TCK")
COLUMNS = [
    "t", "phase", "queue_depth", "queue_running", "jobs_finished", "healthz_ms", "metrics_ms",
    "rss_kib", "hwm_kib", "threads", "fds", "server_cpu_s", "machine_busy_s", "probe_fsync_ms",
    "listen_overflows", "admin_healthz_ms",
]


def listen_overflows():
    """TcpExtListenOverflows of the machine (connections refused by a full accept queue)."""
    with open("/proc/net/netstat") as f:
        lines = f.read().splitlines()
    for head, vals in zip(lines[::2], lines[1::2]):
        if head.startswith("TcpExt:"):
            return dict(zip(head.split()[1:], vals.split()[1:])).get("ListenOverflows", "")
    return ""


def durable_write(d):
    t0 = time.perf_counter()
    tmp, dst = os.path.join(d, ".probe.tmp"), os.path.join(d, "probe")
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
    try:
        os.write(fd, b"x" * 1024)
        os.fsync(fd)
    finally:
        os.close(fd)
    os.rename(tmp, dst)
    dfd = os.open(d, os.O_RDONLY)
    try:
        os.fsync(dfd)
    finally:
        os.close(dfd)
    return (time.perf_counter() - t0) * 1000


def get(host, port, path):
    t0 = time.monotonic()
    c = http.client.HTTPConnection(host, port, timeout=10)
    try:
        c.request("GET", path)
        r = c.getresponse()
        body = r.read()
        return r.status, body, (time.monotonic() - t0) * 1000
    finally:
        c.close()


def healthz(host, port):
    """ms a /healthz on a new connection took; -1 when it failed (not 200, or no answer)."""
    try:
        s, _, ms = get(host, port, "/healthz")
        return ms if s == 200 else -1
    except (OSError, http.client.HTTPException):
        return -1


def proc(pid):
    out = {}
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            k, _, v = line.partition(":")
            if k in ("VmRSS", "VmHWM", "Threads"):
                out[k] = int(v.split()[0])
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    out["cpu"] = (int(fields[11]) + int(fields[12])) / TICK
    out["fds"] = len(os.listdir(f"/proc/{pid}/fd"))
    return out


def machine_busy():
    with open("/proc/stat") as f:
        v = [int(x) for x in f.readline().split()[1:]]
    idle = v[3] + v[4]
    return (sum(v[:8]) - idle) / TICK


def metric(text, name):
    for line in text.splitlines():
        if line.startswith(name + " "):
            return float(line.split()[1])
    return ""


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--addr", required=True)
    ap.add_argument("--pid", type=int, required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--phase-file", required=True)
    ap.add_argument("--interval", type=float, default=0.5)
    ap.add_argument("--probe-dir")
    ap.add_argument("--admin-addr", help="the server's --admin-addr: its /healthz is probed too")
    a = ap.parse_args()
    host, port = a.addr.rsplit(":", 1)
    if a.probe_dir:
        os.makedirs(a.probe_dir, exist_ok=True)
    stop = []
    signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
    with open(a.out, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(COLUMNS)
        next_t = time.monotonic()
        while not stop:
            t = time.time()
            try:
                phase = open(a.phase_file).read().strip()
            except OSError:
                phase = ""
            health_ms = healthz(host, port)
            admin_ms = f"{healthz(*a.admin_addr.rsplit(':', 1)):.2f}" if a.admin_addr else ""
            depth = running = finished = ""
            metrics_ms = -1
            try:
                s, body, metrics_ms = get(host, port, "/metrics")
                if s == 200:
                    text = body.decode()
                    depth = metric(text, "voxd_queue_depth")
                    running = metric(text, "voxd_queue_running")
                    finished = metric(text, "voxd_job_duration_seconds_count")
            except (OSError, http.client.HTTPException):
                pass
            try:
                p = proc(a.pid)
            except OSError:
                break  # the server is gone
            probe = f"{durable_write(a.probe_dir):.3f}" if a.probe_dir else ""
            w.writerow([
                f"{t:.3f}", phase, depth, running, finished, f"{health_ms:.2f}", f"{metrics_ms:.2f}",
                p["VmRSS"], p["VmHWM"], p["Threads"], p["fds"], f"{p['cpu']:.2f}",
                f"{machine_busy():.2f}", probe, listen_overflows(), admin_ms,
            ])
            f.flush()
            next_t += a.interval
            time.sleep(max(0.0, next_t - time.monotonic()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
