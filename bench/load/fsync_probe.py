#!/usr/bin/env python3
"""What one durable small write costs in DIR: N times write 1 KiB to a new temporary file, fsync
it, rename it into place and fsync the directory (the store's pattern for a job record or a
volume's metadata). Prints {"p50_ms": …, "p90_ms": …, "max_ms": …} as JSON."""

import json
import os
import sys
import time

d, n = sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 100
os.makedirs(d, exist_ok=True)
ts = []
dfd = os.open(d, os.O_RDONLY)
for i in range(n):
    t0 = time.perf_counter()
    tmp = os.path.join(d, f".probe-{i}.tmp")
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
    os.write(fd, b"x" * 1024)
    os.fsync(fd)
    os.close(fd)
    os.rename(tmp, os.path.join(d, f"probe-{i}"))
    os.fsync(dfd)
    ts.append((time.perf_counter() - t0) * 1000)
os.close(dfd)
for i in range(n):
    os.unlink(os.path.join(d, f"probe-{i}"))
ts.sort()
print(json.dumps({"p50_ms": round(ts[n // 2], 3), "p90_ms": round(ts[n * 9 // 10], 3),
                  "max_ms": round(ts[-1], 3), "n": n}))
