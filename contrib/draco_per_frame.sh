#!/usr/bin/env bash
# What a web user would ship instead of a dynamic mesh: every captured frame
# compressed on its own with Draco. Each OBJ frame of DIR becomes a GLB
# (Cesium's obj2gltf, no normals or textures added), then gltf-transform's
# `draco` at its defaults (position quantisation 14 bits, or QP bits with
# a second argument); prints the frames' total bytes.
#
#   contrib/draco_per_frame.sh DIR [QP]
#
# The tools are installed once by npm (pinned versions) into
# ${VOLTRACK_DRACO_TOOLS:-target/draco-tools}; the per-frame files go to a
# temporary folder that is removed afterwards. DIR is only read.
set -euo pipefail
dir=${1:?usage: contrib/draco_per_frame.sh DIR [QP]}
qp=${2:-14}
tools=${VOLTRACK_DRACO_TOOLS:-target/draco-tools}
if [ ! -x "$tools/node_modules/.bin/gltf-transform" ] || [ ! -x "$tools/node_modules/.bin/obj2gltf" ]; then
    mkdir -p "$tools"
    npm install --prefix "$tools" --no-audit --no-fund --silent @gltf-transform/cli@4.5.1 obj2gltf@3.2.0 >&2
fi
bin=$(cd "$tools/node_modules/.bin" && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
total=0
frames=0
for obj in "$dir"/*.obj; do
    name=$(basename "$obj" .obj)
    "$bin/obj2gltf" -i "$obj" -o "$work/$name.glb" --binary >/dev/null
    "$bin/gltf-transform" draco "$work/$name.glb" "$work/$name.draco.glb" \
        --quantize-position "$qp" >/dev/null
    total=$((total + $(stat -c %s "$work/$name.draco.glb")))
    frames=$((frames + 1))
done
[ "$frames" -gt 0 ] || { echo "no .obj frames in $dir" >&2; exit 1; }
echo "$dir: $frames frames, Draco per frame (qp $qp): $total bytes"
