#!/usr/bin/env bash
# Runs every shell session of README.md as written and fails when one fails or prints other than
# what the README shows (ids, keys, times and timings masked): scripts/readme_check.py, which
# says how sessions are marked. scripts/test.sh runs it with the binary `cargo test` built; alone
# it builds target/debug/voxd. What the sessions need (curl, jq, python3's venv; numpy comes from
# PyPI into the session's own venv) is installed by scripts/provision.sh readme.
#   scripts/readme-check.sh            # check
#   scripts/readme-check.sh --update   # write what each session printed into README.md (review the diff)
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/provision.sh readme
BIN=${VOXD_README_BIN:-}
if [[ -z $BIN ]]; then
  cargo build --locked --quiet --bin voxd
  BIN=${CARGO_TARGET_DIR:-target}/debug/voxd
fi
for tool in curl jq; do command -v "$tool" >/dev/null || { echo "readme-check: $tool is missing (scripts/provision.sh readme installs it as root)" >&2; exit 1; }; done
exec python3 scripts/readme_check.py --voxd "$BIN" "$@"
