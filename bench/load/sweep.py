#!/usr/bin/env python3
"""After an open-loop run: wait for the queue to drain, then check every accepted job.

Reads the k6 console log (`A <id>` per accepted job, `F <id> <state>` when its poll saw it
final), waits (at most --drain-s) until /metrics shows no job queued or running, then
`GET /v1/jobs/{id}` for every accepted id (one keep-alive connection) and writes a JSON verdict:
accepted, the states k6 saw, the states the sweep saw, and `lost` = accepted jobs that neither
k6's poll nor the sweep saw `succeeded`. The in-process queue keeps the newest 10,000 finished
jobs, so on a server that has run more than that, a 404 in the sweep can be an old job forgotten:
it counts as lost only if k6 did not see it succeed either.
"""

import argparse
import collections
import http.client
import json
import sys
import time


def metrics(conn):
    conn.request("GET", "/metrics")
    r = conn.getresponse()
    text = r.read().decode()
    vals = {}
    for line in text.splitlines():
        if line and not line.startswith("#"):
            k, _, v = line.rpartition(" ")
            vals[k] = float(v)
    return vals


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--addr", required=True)
    ap.add_argument("--console", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--drain-s", type=float, default=120)
    a = ap.parse_args()
    host, port = a.addr.rsplit(":", 1)
    accepted, seen = [], {}
    with open(a.console, errors="replace") as f:
        for line in f:
            # k6 writes console.log lines as logfmt: ... msg="A 1234abcd" ...
            i = line.find('msg="')
            if i < 0:
                continue
            msg = line[i + 5:line.find('"', i + 5)].split()
            if len(msg) == 2 and msg[0] == "A":
                accepted.append(msg[1])
            elif len(msg) == 3 and msg[0] == "F":
                seen[msg[1]] = msg[2]
    conn = http.client.HTTPConnection(host, port, timeout=30)
    t0 = time.monotonic()
    drained = False
    while time.monotonic() - t0 < a.drain_s:
        m = metrics(conn)
        if m.get("voxd_queue_depth", 1) == 0 and m.get("voxd_queue_running", 0) == 0:
            drained = True
            break
        time.sleep(0.2)
    drain_s = time.monotonic() - t0
    swept = collections.Counter()
    lost = []
    for jid in accepted:
        conn.request("GET", f"/v1/jobs/{jid}")
        r = conn.getresponse()
        body = r.read()
        state = json.loads(body).get("state", "?") if r.status == 200 else str(r.status)
        swept[state] += 1
        if state != "succeeded" and seen.get(jid) != "succeeded":
            lost.append({"id": jid, "sweep": state, "k6": seen.get(jid)})
    result = {
        "accepted": len(accepted),
        "distinct_accepted": len(set(accepted)),
        "k6_saw_final": dict(collections.Counter(seen.values())),
        "k6_never_saw_final": sum(1 for j in accepted if j not in seen),
        "drained": drained,
        "drain_s": round(drain_s, 2),
        "sweep": dict(swept),
        "lost": len(lost),
        "lost_examples": lost[:20],
    }
    with open(a.out, "w") as f:
        json.dump(result, f, indent=1)
    print(f"  sweep: {len(accepted)} accepted, sweep states {dict(swept)}, lost {len(lost)}"
          f" (drained after {drain_s:.1f} s)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
