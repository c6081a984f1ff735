#!/usr/bin/env bash
# Generates the Python client's generated part (clients/python/voxd_client/generated/) from
# openapi.yaml with openapi-python-client, pinned exactly (generator-requirements.txt) in a venv
# under ~/.cache (VOXD_CLIENT_GEN_VENV), made once and remade when the pins change. Its post
# hooks (ruff, pinned with it) format the code, so the output depends only on the document, the
# pins and generator-config.yaml: scripts/client-check.sh regenerates it and fails on a diff.
#   clients/python/generate.sh          # regenerate in place
#   clients/python/generate.sh DIR      # generate into DIR instead (DIR is replaced)
# Fails when the generator warns of anything but the expected (the model/* request types it
# cannot send, see generator-config.yaml): an operation, a body or a response left out.
set -euo pipefail
HERE=$(cd "$(dirname "$0")" && pwd)
ROOT=$(cd "$HERE/../.." && pwd)
OUT=${1:-$HERE/voxd_client/generated}
VENV=${VOXD_CLIENT_GEN_VENV:-${XDG_CACHE_HOME:-$HOME/.cache}/voxd/client-gen-venv}
REQS=$HERE/generator-requirements.txt

pin=$(sha256sum "$REQS" | cut -d' ' -f1)
if [[ ! -x $VENV/bin/openapi-python-client || "$(cat "$VENV/.pins" 2>/dev/null)" != "$pin" ]]; then
  echo "generate: installing openapi-python-client ($REQS) into $VENV" >&2
  rm -rf "$VENV"
  python3 -m venv "$VENV"
  "$VENV/bin/pip" install -q --disable-pip-version-check --no-deps -r "$REQS"
  echo "$pin" >"$VENV/.pins"
fi

TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
# ruff (the post hooks) from the venv, and nothing from the caller's environment.
if ! (cd "$TMP" && PATH=$VENV/bin:/usr/bin:/bin RUFF_NO_CACHE=true "$VENV/bin/openapi-python-client" generate \
  --path "$ROOT/openapi.yaml" --config "$HERE/generator-config.yaml" --meta none \
  --output-path "$TMP/generated" >"$TMP/log" 2>&1); then
  cat "$TMP/log" >&2
  echo "generate: openapi-python-client failed" >&2
  exit 1
fi
# Each warning is a "WARNING parsing ..." line, its detail on the next line. Only the request
# body types the generator cannot send are expected.
unexpected=$(awk '/^WARNING/ { w = $0; next }
  w != "" && NF { if ($0 !~ /^Unsupported content type model\/(obj|gltf-binary|gltf-json|stl|ply)$/) print w " " $0; w = "" }
  /^(Unable to parse|Could not|Cannot parse)/ { print }' "$TMP/log")
if [[ -n $unexpected ]]; then
  cat "$TMP/log" >&2
  echo "generate: unexpected warnings (a part of the API would be missing):" >&2
  echo "$unexpected" >&2
  exit 1
fi
grep -q 'ruff is not in PATH' "$TMP/log" && { cat "$TMP/log" >&2; echo "generate: ruff did not run" >&2; exit 1; }
rm -rf "$OUT" "$TMP/generated/.ruff_cache"
mkdir -p "$(dirname "$OUT")"
mv "$TMP/generated" "$OUT"
