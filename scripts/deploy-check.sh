#!/usr/bin/env bash
# Checks the deployment files without Docker or a cluster: hadolint on the Dockerfile,
# docker-compose config and the compose spec's schema on deploy/docker-compose.yml, the
# rendered kustomizations against Kubernetes' schemas (kubernetes-validate --strict), the KEDA
# ScaledObject against KEDA's CRD schema, yamllint, nginx -t and promtool check config on
# deploy/nginx.conf and deploy/prometheus.yml and promtool check/test rules on
# deploy/prometheus-alerts.yml (where installed), and shellcheck. The Python tools are pinned
# (scripts/deploy-requirements.txt) in a venv under ~/.cache that scripts/provision.sh makes once
# and reuses; it also installs docker-compose and shellcheck where it can.
set -euo pipefail
cd "$(dirname "$0")/.."

VENV=${VOXD_DEPLOY_VENV:-${XDG_CACHE_HOME:-$HOME/.cache}/voxd/deploy-venv}
scripts/provision.sh deploy-check   # the venv (made once), docker-compose, shellcheck
B=$VENV/bin
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT

echo "== hadolint Dockerfile"
"$B/hadolint" Dockerfile

echo "== docker-compose config (Debian's docker-compose)"
if command -v docker-compose >/dev/null; then
  docker-compose -f deploy/docker-compose.yml config -q
  docker-compose -f deploy/docker-compose.yml --profile gpu config -q
else
  echo "NOTICE: no docker-compose (not root, or apt failed); skipping docker-compose config"
fi

echo "== check-jsonschema (compose spec)"
"$B/check-jsonschema" --builtin-schema vendor.compose-spec deploy/docker-compose.yml

echo "== kustomizations against Kubernetes' schemas"
# kubectl has kustomize built in; a standalone kustomize does too. Neither comes from a registry
# these machines reach (kustomize is a Go program, not on PyPI, npm or crates.io, and Debian
# has no package), so without them each base manifest is validated as it stands: the base's
# kustomization.yaml is a plain resource list plus common labels and an image tag, so the
# rendered base differs only in those. The overlays (keda, gpu) need a renderer.
render=()
if command -v kustomize >/dev/null; then render=(kustomize build)
elif command -v kubectl >/dev/null && kubectl kustomize --help >/dev/null 2>&1; then render=(kubectl kustomize)
fi
# Kubernetes' schemas have no CRDs: the ScaledObject is checked below, the rest here.
split_k8s() { # FILE -> FILE.k8s (no ScaledObject) and FILE.keda
  "$B/python" - "$1" <<'PY'
import sys, yaml
src = sys.argv[1]
docs = [d for d in yaml.safe_load_all(open(src)) if d]
with open(src + ".k8s", "w") as k8s, open(src + ".keda", "w") as keda:
    yaml.safe_dump_all([d for d in docs if d.get("kind") != "ScaledObject"], k8s)
    yaml.safe_dump_all([d for d in docs if d.get("kind") == "ScaledObject"], keda)
PY
}
keda_files=(deploy/k8s/keda/scaledobject.yaml)
if ((${#render[@]})); then
  for dir in deploy/k8s deploy/k8s/keda deploy/k8s/overlays/gpu; do
    out=$TMP/$(echo "$dir" | tr / _).yaml
    "${render[@]}" "$dir" >"$out"
    split_k8s "$out"
    echo "-- $dir ($(grep -c '^kind:' "$out") resources)"
    "$B/kubernetes-validate" --strict --quiet "$out.k8s"
    keda_files+=("$out.keda")
  done
  grep -q 'nvidia.com/gpu: 1' "$TMP/deploy_k8s_overlays_gpu.yaml" || { echo "gpu overlay: no nvidia.com/gpu limit"; exit 1; }
  if grep -q '^kind: HorizontalPodAutoscaler' "$TMP/deploy_k8s_keda.yaml"; then
    echo "keda overlay: the CPU HPA is still there next to the ScaledObject"; exit 1
  fi
else
  echo "NOTICE: no kubectl or kustomize; validating deploy/k8s/base/*.yaml one by one, overlays not rendered"
  for f in deploy/k8s/base/*.yaml; do
    [[ $(basename "$f") == kustomization.yaml ]] && continue
    "$B/kubernetes-validate" --strict --quiet "$f"
  done
fi

echo "== KEDA ScaledObject against KEDA's CRD schema"
"$B/python" scripts/deploy-keda-check.py "${keda_files[@]}"

echo "== yamllint"
"$B/yamllint" --strict .yamllint deploy

# deploy/local.sh (the compose topology natively, scripts/deploy-e2e.sh) renders nginx.conf and
# prometheus.yml for 127.0.0.1: nginx -t on its nginx.conf (compose's resolves only inside
# compose's network), promtool on prometheus.yml as compose mounts it and as rendered.
echo "== nginx -t and promtool check config (deploy/nginx.conf, deploy/prometheus.yml)"
VOXD_PYTHON=$B/python deploy/local.sh render "$TMP/local" >/dev/null
if command -v nginx >/dev/null || [[ -x /usr/sbin/nginx ]]; then
  nginx=$(command -v nginx || echo /usr/sbin/nginx)
  "$nginx" -t -q -p "$TMP/local/nginx/" -c "$TMP/local/nginx.conf" -g 'daemon off;' >"$TMP/nginx-t.log" 2>&1 \
    || { cat "$TMP/nginx-t.log"; echo "nginx -t refused deploy/nginx.conf (as deploy/local.sh renders it)"; exit 1; }
  echo "-- nginx -t: ok"
else
  echo "NOTICE: no nginx; skipping nginx -t"
fi
if command -v promtool >/dev/null; then
  promtool check config deploy/prometheus.yml
  promtool check config "$TMP/local/prometheus.yml"
  # The example alerting rules, and their unit tests.
  promtool check rules deploy/prometheus-alerts.yml
  promtool test rules deploy/prometheus-alerts.test.yml
else
  echo "NOTICE: no promtool (apt-get install prometheus); skipping promtool check config and rules"
fi

echo "== shellcheck (deploy/local.sh, scripts/*.sh)"
if command -v shellcheck >/dev/null; then
  shellcheck deploy/local.sh scripts/*.sh
else
  echo "NOTICE: no shellcheck (not root, or apt failed); skipping shellcheck"
fi

echo "deploy-check: all clean"
