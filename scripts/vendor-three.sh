#!/usr/bin/env bash
# Vendors three.js for the viewer page (GET /v1/volumes/{id}/view) into assets/viewer/vendor/:
# the minified module build, its core, OrbitControls and the licence, from the npm registry at a
# pinned version. The files are committed (the binary embeds them, so the page works offline);
# run this only to change the version.
set -euo pipefail
VERSION=0.181.2
cd "$(dirname "$0")/.."
out=assets/viewer/vendor
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
(cd "$tmp" && npm pack --silent "three@$VERSION" >/dev/null && tar xzf "three-$VERSION.tgz")
mkdir -p "$out"
cp "$tmp/package/build/three.module.min.js" "$tmp/package/build/three.core.min.js" "$out/"
cp "$tmp/package/examples/jsm/controls/OrbitControls.js" "$out/"
cp "$tmp/package/LICENSE" "$out/LICENSE-three.txt"
echo "three@$VERSION (npm), MIT: three.module.min.js, three.core.min.js, examples/jsm/controls/OrbitControls.js" > "$out/VERSION"
ls -la "$out"
