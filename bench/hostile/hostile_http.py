"""The HTTP plumbing of `hostile.py` (split from it, which imports these): a voxd server started per
case (`Server`), requests and raw exchanges on their own sockets with deadlines, and the slow
reader."""
import json
import os
import select
import shutil
import socket
import subprocess
import tempfile
import threading
import time

MiB = 1 << 20


# ---------------------------------------------------------------------------------------------
# The server under test


class Server:
    """A fresh `voxd serve` (or the one at --addr). hwm() is its VmHWM in bytes, or None."""

    def __init__(self, a, extra=(), data=None):
        self.proc, self.own_data = None, False
        if a.addr:
            self.addr, self.pid = a.addr, a.pid
            return
        if data is None:
            data = tempfile.mkdtemp(prefix="voxd-hostile-")
            self.own_data = True
        self.data = data
        cmd = [a.voxd, "serve", "--addr", "127.0.0.1:0", "--data-dir", data, "--engine", "cpu",
               "--max-memory", str(a.max_memory), *map(str, extra)]
        self.log = open(a.log, "ab")
        self.log.write(("\n$ " + " ".join(cmd) + "\n").encode())
        self.log.flush()
        self.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=self.log,
                                     env=dict(os.environ, VOXD_LOG=os.environ.get("VOXD_LOG", "warn")),
                                     start_new_session=True)
        r, _, _ = select.select([self.proc.stdout], [], [], 60)
        line = self.proc.stdout.readline().decode() if r else ""
        if "http://" not in line:
            self.stop()
            raise RuntimeError(f"server did not start: {line!r} (see {a.log})")
        self.addr = line.strip().split("http://", 1)[1]
        self.pid = self.proc.pid
        threading.Thread(target=self._drain, daemon=True).start()

    def _drain(self):
        for line in self.proc.stdout:
            self.log.write(line)

    def _status(self, key):
        if not self.pid:
            return None
        try:
            with open(f"/proc/{self.pid}/status") as f:
                for line in f:
                    if line.startswith(key + ":"):
                        return int(line.split()[1]) * 1024
        except OSError:
            return None
        return None

    def hwm(self):
        return self._status("VmHWM")

    def rss(self):
        return self._status("VmRSS")

    def fds(self):
        try:
            return len(os.listdir(f"/proc/{self.pid}/fd")) if self.pid else None
        except OSError:
            return None

    @property
    def hostport(self):
        h, p = self.addr.rsplit(":", 1)
        return h, int(p)

    def stop(self):
        if self.proc is None:
            return
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(15)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, 9)
                self.proc.wait()
        self.proc = None
        if self.own_data:
            shutil.rmtree(self.data, ignore_errors=True)


# ---------------------------------------------------------------------------------------------
# A small HTTP/1.1 client that sees a response sent before the body is (if the server answers
# early and closes, http.client only reports the broken pipe)


class Resp:
    def __init__(self, status, headers=None, body=b"", err=None):
        self.status, self.headers, self.body, self.err = status, headers or {}, body, err

    @property
    def key(self):
        """The status as a table shows it: 503, 413, or the exception's name."""
        return str(self.status) if self.status else (self.err or "no-answer")

    @property
    def problem(self):
        if "problem+json" not in self.headers.get("content-type", ""):
            return None
        try:
            return json.loads(self.body).get("type", "").rsplit("/", 1)[-1]
        except ValueError:
            return "?"


def read_response(s, deadline, buf=b""):
    while b"\r\n\r\n" not in buf:
        left = deadline - time.monotonic()
        if left <= 0:
            return Resp(None, err="timeout", body=buf)
        s.settimeout(left)
        try:
            d = s.recv(65536)
        except socket.timeout:
            return Resp(None, err="timeout")
        except OSError as e:
            return Resp(None, err=type(e).__name__)
        if not d:
            return Resp(None, err="closed" if not buf else "cut-head")
        buf += d
    head, rest = buf.split(b"\r\n\r\n", 1)
    lines = head.decode("latin-1").split("\r\n")
    try:
        status = int(lines[0].split()[1])
    except (IndexError, ValueError):
        return Resp(None, err="bad-status-line")
    headers = {}
    for ln in lines[1:]:
        k, _, v = ln.partition(":")
        headers[k.strip().lower()] = v.strip()
    n = headers.get("content-length")
    if n is not None and n.isdigit():
        n = int(n)
        while len(rest) < n and time.monotonic() < deadline:
            s.settimeout(max(0.01, deadline - time.monotonic()))
            try:
                d = s.recv(min(1 << 20, n - len(rest)))
            except OSError:
                break
            if not d:
                break
            rest += d
    return Resp(status, headers, rest)


def request(addr, method, path, body=b"", headers=None, timeout=120, chunked=False, src=None):
    """Send a request (body: bytes, sent while watching for an early answer) and read the answer.
    Never raises for network errors: they come back as Resp.err."""
    host, port = addr.rsplit(":", 1)
    deadline = time.monotonic() + timeout
    h = {"Host": "x", **(headers or {})}
    if chunked:
        h["Transfer-Encoding"] = "chunked"
    elif body or method in ("POST", "PUT"):
        h.setdefault("Content-Length", str(len(body)))
    head = f"{method} {path} HTTP/1.1\r\n" + "".join(f"{k}: {v}\r\n" for k, v in h.items()) + "\r\n"
    try:
        s = socket.create_connection((host, int(port)), timeout=min(timeout, 30),
                                     source_address=(src, 0) if src else None)
    except OSError as e:
        return Resp(None, err=type(e).__name__)
    try:
        out = [head.encode("latin-1")]
        if chunked:
            for i in range(0, len(body), MiB):
                piece = body[i:i + MiB]
                out += [b"%x\r\n" % len(piece), piece, b"\r\n"]
            out.append(b"0\r\n\r\n")
        else:
            out.append(body)
        for part in out:
            mv, off = memoryview(part), 0
            while off < len(mv):
                left = deadline - time.monotonic()
                if left <= 0:
                    return Resp(None, err="timeout")
                r, w, _ = select.select([s], [s], [], min(left, 5))
                if r:  # an answer (or a close) before the body is all sent
                    return read_response(s, deadline)
                if w:
                    try:
                        off += s.send(mv[off:off + 262144])
                    except OSError as e:
                        got = read_response(s, min(deadline, time.monotonic() + 2))
                        return got if got.status else Resp(None, err=type(e).__name__)
        return read_response(s, deadline)
    finally:
        s.close()


def slow_reader(addr, path, rate, stop, out, i):
    host, port = addr.rsplit(":", 1)
    s = socket.socket()
    s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 16384)
    got, t0 = 0, time.monotonic()
    try:
        s.settimeout(30)
        s.connect((host, int(port)))
        s.sendall(f"GET {path} HTTP/1.1\r\nHost: x\r\n\r\n".encode())
        buf = b""
        while b"\r\n\r\n" not in buf:
            d = s.recv(4096)
            if not d:
                break
            buf += d
        if b"\r\n\r\n" not in buf:
            out[i] = ("closed", 0, None, time.monotonic() - t0)
            return
        head, rest = buf.split(b"\r\n\r\n", 1)
        status = int(head.split(b" ", 2)[1])
        out[i] = (status, len(rest), None, time.monotonic() - t0)
        if status != 200:
            return
        got = len(rest)
        step = rate / 10
        while not stop.is_set():
            want, t = step, time.monotonic()
            while want > 0:
                d = s.recv(int(min(want, 65536)))
                if not d:
                    out[i] = (status, got, "closed", time.monotonic() - t0)
                    return
                got += len(d)
                want -= len(d)
            out[i] = (status, got, None, time.monotonic() - t0)
            time.sleep(max(0.0, 0.1 - (time.monotonic() - t)))
    except OSError as e:
        out[i] = (out[i][0] if out[i] else type(e).__name__, got, type(e).__name__, time.monotonic() - t0)
    finally:
        s.close()


def raw(addr, data, timeout, then_send=None):
    """Send bytes (then_send: [(delay, bytes)] later), read one answer; (Resp, seconds)."""
    host, port = addr.rsplit(":", 1)
    t = time.monotonic()
    deadline = t + timeout
    try:
        s = socket.create_connection((host, int(port)), timeout=10)
    except OSError as e:
        return Resp(None, err=type(e).__name__), time.monotonic() - t
    try:
        try:
            s.sendall(data)
        except OSError:
            pass
        for delay, more in then_send or []:
            r, _, _ = select.select([s], [], [], delay)
            if r:
                break
            try:
                s.sendall(more)
            except OSError:
                break
        return read_response(s, deadline), time.monotonic() - t
    finally:
        s.close()
