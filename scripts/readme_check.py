#!/usr/bin/env python3
"""Runs the shell sessions of README.md as written and compares what they print with what the
README shows (scripts/readme-check.sh calls it; scripts/test.sh runs that).

Every fenced block that holds a `$ ` line must be preceded by a marker line:

    <!-- session: NAME -->              run it (a server is on 127.0.0.1:8080 first)
    <!-- session: NAME (no server) -->  run it without the service
    <!-- session: skip: REASON -->      not run here; the reason says what checks it instead

A block with `$ ` lines and no marker is an error, so a new session cannot be added untested.

Each session runs in one bash (its variables and background jobs carry from line to line), in
a scratch directory that mirrors the checkout (symbolic links to its files), with `voxd` on
PATH. The service the README's setup command would have started (`./scripts/run.sh`: `voxd
serve` on 127.0.0.1:8080) is started by this script on a free port, and `127.0.0.1:8080` in the
commands is rewritten to it; other 127.0.0.1 ports in the commands (a second server a session
starts) get free ports too. Every command must succeed (exit 0) and print what the README
shows after masking what differs from run to run: ids (16 hex digits), keys, hashes, times,
timings, content lengths. JSON lines are compared as JSON with those fields masked. An
expected line `…` matches any number of lines; `...` within a line matches any text.

    readme_check.py --voxd BIN [--print] [--update] [--only NAME]
      --print: show each session as it ran; --update: write what each session printed into
      README.md in place of what it shows (then review the diff)
"""

import argparse
import json
import os
import re
import select
import signal
import socket
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MARK = re.compile(r"^<!-- session: (.*?) -->\s*$")
# Values that differ between runs, masked in both the expected and the actual text.
MASKS = [
    (re.compile(r"voxd_[A-Za-z0-9_-]{43}"), "<key>"),
    (re.compile(r"\b[0-9a-f]{64}\b"), "<sha256>"),
    (re.compile(r"\b[0-9a-f]{16}\b"), "<id>"),
    (re.compile(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d(\.\d+)?Z"), "<time>"),
    (re.compile(r"(?i)^(content-length|date): .*$"), r"\1: <n>"),
    (re.compile(r"127\.0\.0\.1:\d+"), "127.0.0.1:<port>"),
    (re.compile(r"\b\d+\.\d+ s \((load|read) [^)]*\)"), "<timings>"),  # the CLI's summary
]
# JSON members whose values differ between runs (masked wherever they are).
VOLATILE = {"created", "timings", "request_id", "position", "progress", "engine_s", "ms",
            "duration_s", "duration_ms", "secs", "elapsed_s", "timestamp", "time"}


def blocks(text):
    """(marker, first line number, lines) of every fenced block holding a `$ ` line."""
    lines = text.split("\n")
    out, i, marker = [], 0, None
    while i < len(lines):
        m = MARK.match(lines[i])
        if m:
            marker = m.group(1)
        elif lines[i].lstrip().startswith("```"):
            fence = lines[i].lstrip()[:3]
            indent = len(lines[i]) - len(lines[i].lstrip())
            j = i + 1
            while j < len(lines) and not lines[j].lstrip().startswith(fence):
                j += 1
            body = [l[indent:] for l in lines[i + 1 : j]]
            if any(l.startswith("$ ") for l in body):
                out.append((marker, i + 1, j, indent, body))
            marker = None
            i = j
        elif lines[i].strip():
            marker = None if not lines[i].startswith("<!--") else marker
        i += 1
    return out


def steps(body):
    """[(command, expected lines)]: `$ ` lines (with `\\` continuations) and what follows."""
    out = []
    i = 0
    while i < len(body):
        if body[i].startswith("$ "):
            cmd = body[i][2:]
            while cmd.endswith("\\") and i + 1 < len(body):
                i += 1
                cmd = cmd + "\n" + body[i]
            here = re.search(r"<<-?\s*'?\"?(\w+)'?\"?", cmd)
            if here:  # a here-document: its lines up to the terminator belong to the command
                while i + 1 < len(body):
                    i += 1
                    cmd = cmd + "\n" + body[i]
                    if body[i].strip() == here.group(1):
                        break
            out.append([cmd, []])
        elif out:
            out[-1][1].append(body[i])
        i += 1
    for s in out:
        while s[1] and not s[1][-1].strip():
            s[1].pop()
    return out


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def mask(s):
    for r, to in MASKS:
        s = r.sub(to, s)
    return s


def mask_json(v):
    if isinstance(v, dict):
        return {k: "<volatile>" if k in VOLATILE else mask_json(x) for k, x in v.items()}
    if isinstance(v, list):
        return [mask_json(x) for x in v]
    if isinstance(v, str):
        return mask(v)
    return v


def as_json(line):
    line = line.strip()
    if not line.startswith(("{", "[")):
        return None
    try:
        return json.loads(line)
    except ValueError:
        return None


def line_matches(exp, act):
    je, ja = as_json(exp), as_json(act)
    if je is not None:
        if ja is None:
            return False
        # A job's state right after its submission depends on how fast the worker took it.
        for j in (je, ja):
            if isinstance(j, dict) and j.get("state") in ("queued", "running"):
                j["state"] = "queued|running"
        return mask_json(je) == mask_json(ja)
    pattern = ".*".join(re.escape(p) for p in mask(exp.rstrip()).split("..."))
    return re.fullmatch(pattern, mask(act.rstrip())) is not None


def output_matches(expected, actual):
    """Expected lines against actual ones; `…` alone matches any run of lines."""
    if not expected:
        return not actual
    if expected[0].strip() == "…":
        return any(output_matches(expected[1:], actual[k:]) for k in range(len(actual) + 1))
    return bool(actual) and line_matches(expected[0], actual[0]) and output_matches(expected[1:], actual[1:])


class Shell:
    """One bash for a session: commands go in through files, output comes back to a marker."""

    def __init__(self, cwd, env):
        self.cwd = cwd
        self.p = subprocess.Popen(
            ["bash", "--noprofile", "--norc"], cwd=cwd, env=env, stdin=subprocess.PIPE,
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, start_new_session=True)
        self.n = 0
        self.buf = b""

    def run(self, cmd, timeout):
        self.n += 1
        path = os.path.join(self.cwd, f".readme-step-{self.n}.sh")
        with open(path, "w") as f:
            f.write(cmd + "\n")
        marker = f"__readme_step_{self.n}_done__"
        self.p.stdin.write(f"source {path} </dev/null; printf '\\n{marker} %s\\n' $?\n".encode())
        self.p.stdin.flush()
        end = time.monotonic() + timeout
        pat = re.compile(rb"\n" + marker.encode() + rb" (\d+)\n")
        while True:
            m = pat.search(self.buf)
            if m:
                out, self.buf = self.buf[: m.start()], self.buf[m.end():]
                os.unlink(path)
                return int(m.group(1)), out.decode(errors="replace")
            left = end - time.monotonic()
            if left <= 0:
                return None, self.buf.decode(errors="replace")
            r, _, _ = select.select([self.p.stdout], [], [], left)
            if r:
                chunk = os.read(self.p.stdout.fileno(), 65536)
                if not chunk:
                    return None, self.buf.decode(errors="replace")
                self.buf += chunk

    def close(self):
        try:
            os.killpg(self.p.pid, signal.SIGTERM)
        except ProcessLookupError:
            pass
        try:
            self.p.wait(5)
        except subprocess.TimeoutExpired:
            os.killpg(self.p.pid, signal.SIGKILL)
            self.p.wait()


def mirror(dst):
    """A scratch directory with a link to every top-level entry of the checkout but what a run
    makes (so that files a session writes land in the scratch directory)."""
    skip = {"target", ".venv", "voxd-data", ".git", ".device", ".gl"}
    for name in os.listdir(ROOT):
        if name not in skip:
            os.symlink(os.path.join(ROOT, name), os.path.join(dst, name))


def start_server(voxd, port, work):
    log = open(os.path.join(work, "serve.log"), "w")
    p = subprocess.Popen(
        [voxd, "serve", "--addr", f"127.0.0.1:{port}", "--data-dir", os.path.join(work, "data")],
        stdout=log, stderr=subprocess.STDOUT, start_new_session=True, cwd=work)
    for _ in range(300):
        try:
            with socket.create_connection(("127.0.0.1", port), 0.2):
                return p
        except OSError:
            if p.poll() is not None:
                break
            time.sleep(0.1)
    p.kill()
    sys.exit(f"readme-check: voxd serve did not start; see {work}/serve.log")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--voxd", required=True)
    ap.add_argument("--readme", default=os.path.join(ROOT, "README.md"))
    ap.add_argument("--print", action="store_true")
    ap.add_argument("--update", action="store_true")
    ap.add_argument("--only", help="run only this session")
    args = ap.parse_args()
    voxd = os.path.abspath(args.voxd)
    with open(args.readme) as f:
        text = f.read()
    found = blocks(text)
    failures, ran, skipped, updates = [], 0, [], []
    for marker, line, end, indent, body in found:
        if marker is None:
            failures.append(f"README.md:{line}: a block with `$ ` lines has no `<!-- session: ... -->` marker")
            continue
        if marker.startswith("skip:"):
            skipped.append(f"README.md:{line}: {marker}")
            continue
        name = marker.split(" (")[0]
        if args.only and name != args.only:
            continue
        ran += 1
        with tempfile.TemporaryDirectory(prefix=f"readme-{name}-") as work:
            mirror(work)
            bindir = os.path.join(work, ".bin")
            os.mkdir(bindir)
            os.symlink(voxd, os.path.join(bindir, "voxd"))
            env = dict(os.environ, PATH=bindir + ":" + os.environ["PATH"], VOXD_ENGINE="cpu")
            env.pop("VOXD_LOG", None)
            ports = {"8080": str(free_port())}
            server = None if "(no server)" in marker else start_server(voxd, int(ports["8080"]), work)
            shell = Shell(work, env)
            transcript = []
            try:
                for cmd, expected in steps(body):
                    for p in sorted(set(re.findall(r"127\.0\.0\.1:(\d+)", cmd))):
                        ports.setdefault(p, str(free_port()))
                    real = re.sub(r"127\.0\.0\.1:(\d+)", lambda m: "127.0.0.1:" + ports[m.group(1)], cmd)
                    # `export PATH="$PWD/target/release:$PATH"` (after ./scripts/run.sh built it)
                    # finds the binary under test instead.
                    real = real.replace("$PWD/target/release", bindir)
                    rc, out = shell.run(real, timeout=300)
                    lines = [l.rstrip("\r") for l in out.rstrip("\n").split("\n")] if out.strip() else []
                    transcript += ["$ " + cmd] + lines
                    if args.print:
                        print(f"$ {cmd}")
                        print("\n".join(lines))
                    if rc != 0:
                        failures.append(f"README.md:{line} [{name}] `{cmd}` exited {rc}:\n" + out[-3000:])
                        break
                    if not output_matches(expected, lines):
                        failures.append(
                            f"README.md:{line} [{name}] `{cmd}` printed\n  "
                            + "\n  ".join(lines[:40])
                            + "\nbut the README shows\n  "
                            + "\n  ".join(expected[:40]))
                else:
                    updates.append((line, end, indent, transcript))
            finally:
                shell.close()
                if server:
                    server.terminate()
                    try:
                        server.wait(10)
                    except subprocess.TimeoutExpired:
                        server.kill()
    for s in skipped:
        print(f"readme-check: not run: {s}")
    if args.update and updates:
        lines = text.split("\n")
        for start, end, indent, transcript in sorted(updates, reverse=True):
            lines[start:end] = [(" " * indent + t) if t else "" for t in "\n".join(transcript).split("\n")]
        with open(args.readme, "w") as f:
            f.write("\n".join(lines))
        print(f"readme-check: {len(updates)} session(s) written into {args.readme}")
        return
    if failures:
        print("\n\n".join(failures), file=sys.stderr)
        sys.exit(f"readme-check: {len(failures)} failure(s) in {ran} session(s)")
    print(f"readme-check: {ran} session(s) ran as the README shows; {len(skipped)} not run (above)")


if __name__ == "__main__":
    main()
