"""The soak's clients (split from driver.py, which imports them): `Client` threads uploading,
voxelizing, downloading, combining and deleting on their own connections (`Conn`), with malformed
requests among them (`bad_case`)."""
import gzip
import http.client
import json
import os
import random
import socket
import threading
import time
import urllib.parse

MAX_VOLUMES = 40  # the clients delete volumes to keep the store near this
MAX_PENDING_PER_CLIENT = 6
HEAVY_FIRST_GAP_S = 12  # the first pass over the large jobs (during warm-up)
HEAVY_GAP_S = 30  # afterwards

# The aligned grid family: voxel size 1/32, origins a whole number of voxels from BASE.
VS = 0.03125
BASE = (-0.75, -0.8125, -0.75)


def problem_type(body):
    try:
        return json.loads(body).get("type", "").rsplit("/", 1)[-1]
    except Exception:
        return ""


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


def grid_q(g):
    return (
        "origin=%s&voxel_size=%s&dims=%s"
        % (",".join(repr(x) for x in g["origin"]), repr(g["voxel_size"]), ",".join(str(d) for d in g["dims"]))
    )


# ---------------------------------------------------------------------------------------------
# Clients


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
            # (A slice given with a projection is drawn: openapi.yaml, since 97c9a41.)
            ("preview: unknown projection", "GET", f"/v1/volumes/{v}/preview.png?projection=median", None, {}, (400,)),
            ("normals: bad points", "GET", f"/v1/volumes/{v}/normals?points=1,2", None, {}, (400, 404)),
            ("query: 3 numbers as a ray", "POST", f"/v1/volumes/{v}/query", b'{"rays":[{"origin":[0,0]}]}', {"Content-Type": "application/json"}, (400, 404, 422)),
            ("morphology: bad kernel", "POST", f"/v1/volumes/{v}/morphology", b'{"op":"dilate","radius":1,"kernel":"star"}', {"Content-Type": "application/json"}, (400, 404, 422)),
        ]
    name, method, path, body, hdrs, ok = rng.choice(cases + with_vol)
    r = conn.req(method, path, "(malformed requests)", body, hdrs, expect=ok)
    with st.lock:
        st.bad_cases[(name, r[0] if r else "conn-error")] += 1
