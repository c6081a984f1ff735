#!/usr/bin/env bash
# The API contract, checked both ways: openapi.yaml is valid OpenAPI 3.0 (openapi-spec-validator),
# and the real service keeps to it (schemathesis, generated from openapi.yaml, against
# `voxd serve --engine cpu` on 127.0.0.1 with an ephemeral port and a scratch data directory).
# scripts/test.sh runs it; it can run alone (it builds target/debug/voxd).
#
# Fails on: an invalid document, any 5xx, a response whose status, content type, headers or body
# the document does not allow, a request the document forbids that is accepted, a request it
# allows that is refused for its form (positive_data_acceptance; see the statuses below), and
# the stateful checks. VOXD_CONTRACT_EXAMPLES (default 30; more for a deeper run) and
# VOXD_CONTRACT_SEED (default 1) bound and fix the generated cases; VOXD_CONTRACT_REPORT=DIR
# keeps a HAR of every exchange there. schemathesis runs in a
# scratch directory with its cache off, so no earlier run's examples are replayed and nothing
# is left in the tree. The tools live in a venv under ~/.cache (VOXD_CONTRACT_VENV), pinned
# exactly (every transitive package too, for Python 3.11) by scripts/provision.sh, which makes
# it once and reuses it.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD

EXAMPLES=${VOXD_CONTRACT_EXAMPLES:-30}
SEED=${VOXD_CONTRACT_SEED:-1}
VENV=${VOXD_CONTRACT_VENV:-${XDG_CACHE_HOME:-$HOME/.cache}/voxd/contract-venv}

# ---- the tools (pinned in scripts/provision.sh; installed there once, a probe after that) ----
scripts/provision.sh contract

# ---- the document ----
"$VENV/bin/openapi-spec-validator" openapi.yaml

# ---- the service ----
BIN=${VOXD_CONTRACT_BIN:-}   # a voxd binary to check instead of building target/debug/voxd
if [[ -z $BIN ]]; then
  cargo build --locked --quiet --bin voxd
  BIN=${CARGO_TARGET_DIR:-target}/debug/voxd
fi
WORK=$(mktemp -d)
# shellcheck source=scripts/serve-lib.sh
. scripts/serve-lib.sh
cleanup() {
  voxd_stop
  rm -rf "$WORK"
}
trap cleanup EXIT
# A voxel budget of 128³: the document's example mesh makes real jobs, and at the default budget
# (1024³) one of them could keep the two cores busy for minutes.
voxd_start contract "$BIN" "$WORK" --engine cpu --max-voxels 2097152
URL=$VOXD_URL

# Real resources, so that the generated requests reach more than 404s: two aligned volumes (for
# CSG and intersect), one to delete, one job.
read -r VOL VOL2 VOL_DEL JOB < <("$VENV/bin/python" - "$URL" tests/data/Box.gltf <<'PY'
import json, sys, urllib.request
url, mesh = sys.argv[1], open(sys.argv[2], "rb").read()
grid = "origin=-1,-1,-1&voxel_size=0.25&dims=8,8,8"
def post(query):
    req = urllib.request.Request(f"{url}/v1/voxelize?{grid}{query}", data=mesh, method="POST",
                                 headers={"Content-Type": "model/gltf+json"})
    with urllib.request.urlopen(req, timeout=60) as r:
        return json.load(r)["id"]
print(post("&wait=60"), post("&wait=60"), post("&wait=60"), post(""))
PY
)
[[ -n ${JOB:-} ]] || { echo "contract: could not store the seed volumes" >&2; exit 1; }

# Every check but ignored_auth and object_level_authorization (they need auth, which voxd has
# not). positive_data_acceptance holds the document to its other half: a request it allows is
# one the service takes. It may still be refused for what its content means, never for its form;
# so 400 (the request breaks the document) is never an allowed answer to valid data. Allowed:
#   2xx, 304  taken (304: If-None-Match names the current ETag);
#   404       a volume or job id that names nothing stored, or a preview slice the volume's grid
#             does not have (the document cannot know stored ids or dims);
#   409       a job that has already finished cannot be canceled;
#   412       an If-Match the stored volume's ETags do not meet (an empty or made-up list of
#             entity tags: the document cannot know the stored ETags), or an If-None-Match on
#             DELETE that names one;
#   416       a Range past the end of the stored volume's bytes (the document cannot know them);
#   422       well formed but not workable with what is stored: grids that do not line up, a
#             density volume where bits are needed, an empty intersection, a grid or picture over
#             the server's voxel or pixel budget, and for uploads a body that is no usable mesh
#             (random bytes are no mesh);
#   429       the job queue is full (a server state);
#   5xx       not_a_server_error's to judge (it fails the run on any 5xx).
# And for uploads only (POST /v1/voxelize):
#   413       a body over the server's --max-body-bytes (a server setting, not in the document);
#   415       a body whose format cannot be told from its bytes (application/octet-stream asks the
#             server to sniff; RFC 9110 15.5.16 lets 415 come from inspecting the content);
#   400       the grid's parameters in a combination the document allows only in words
#             (resolution with voxel_size, origin without dims, ...): OpenAPI 3.0 has no way to
#             say which query parameters go together, and they are plain parameters so that
#             generated clients can send them.
# And for downloads (GET /v1/volumes/{id}/data), 400 for the same reason: `attributes` goes with
# format npy, raw and indices only, a combination the document states in words.
config() {
  cat <<EOF
suppress-health-check = ["filter_too_much"]
cache.enabled = false
# Query values with no wire form are sent as JSON text (see the file).
hooks = "$ROOT/scripts/contract_hooks.py"

[checks]
ignored_auth.enabled = false
object_level_authorization.enabled = false
positive_data_acceptance.expected-statuses = ["2xx", "304", "404", "409", "412", "416", "422", "429", "5xx"]

[parameters]
"path.id" = "$VOL"

[[operations]]
include-name = "POST /v1/voxelize"
checks.positive_data_acceptance.expected-statuses = ["2xx", "400", "413", "415", "422", "429", "5xx"]

[[operations]]
include-name = "GET /v1/volumes/{id}/data"
checks.positive_data_acceptance.expected-statuses = ["2xx", "304", "400", "404", "409", "412", "416", "422", "429", "5xx"]

[[operations]]
include-name = "DELETE /v1/volumes/{id}"
parameters = { "path.id" = "$VOL_DEL" }

[[operations]]
include-path-regex = "^/v1/jobs/"
parameters = { "path.id" = "$JOB" }

# radius fixed at 1: larger sphere radii are unbounded work (issue 11, defect 4).
[[operations]]
include-name = "POST /v1/volumes/{id}/morphology"
parameters = { "path.id" = "$VOL", "body.radius" = 1 }

[[operations]]
include-name = "POST /v1/volumes/intersect"
parameters = { "body.a" = "$VOL", "body.b" = "$VOL2" }

# Operands drawn from the stored volumes most of the time (a dictionary, not a fixed override,
# which would turn a bare-id body into an object without "op").
[dictionaries.volumes]
values = ["$VOL", "$VOL2"]

[[operations]]
include-name = "POST /v1/volumes/csg"
parameters = { "body.operands[*]" = { dictionary = "volumes", probability = 0.9 }, "body.operands[*].operands[*]" = { dictionary = "volumes", probability = 0.9 } }
EOF
}

st() { # $1: config file; the rest: more options
  local cfg=$1
  shift
  (cd "$WORK" && NO_COLOR=1 "$VENV/bin/st" --config-file "$cfg" run "$ROOT/openapi.yaml" \
    --url "$URL" --max-examples "$EXAMPLES" --seed "$SEED" --workers 1 --request-timeout 60 "$@")
}

config >"$WORK/gate.toml"
report=()
if [[ -n ${VOXD_CONTRACT_REPORT:-} ]]; then # a folder for a HAR of every exchange
  mkdir -p "$VOXD_CONTRACT_REPORT"
  report=(--report har --report-dir "$(cd "$VOXD_CONTRACT_REPORT" && pwd)")
fi
status=0
st "$WORK/gate.toml" "${report[@]}" || status=$?
voxd_alive contract

if [[ $status != 0 ]]; then
  echo "contract: schemathesis found responses that break openapi.yaml (above)" >&2
  exit "$status"
fi
echo "contract: openapi.yaml is valid and the service keeps to it"
