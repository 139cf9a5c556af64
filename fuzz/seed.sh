#!/usr/bin/env bash
# Seeds fuzz/corpus/<target>/ with the committed fixtures, binvox grids
# voxelised from them, the hand-written inputs under seeds/ (every kind of
# line, attribute and accessor the readers handle) and the past crashers
# under ../tests/corpus/.
set -euo pipefail
cd "$(dirname "$0")"
mkdir -p corpus/obj corpus/ply corpus/gltf corpus/binvox
cp ../fixtures/shapes/*.obj ../fixtures/bending_bar/frame_0.obj corpus/obj/
cp ../fixtures/shapes/*.ply corpus/ply/
cp ../fixtures/shapes/*.glb corpus/gltf/
# voxelize replaces its output folder whole and refuses one holding other
# files (the corpus grows as the fuzzer runs): written apart, then copied.
grids=$(mktemp -d)
cargo run --release --quiet --manifest-path ../Cargo.toml -- \
    voxelize ../fixtures/shapes/cube.obj ../fixtures/shapes/torus.obj ../fixtures/shapes/open_cup.obj -r 12 -o "$grids/binvox" >/dev/null 2>&1
cp "$grids"/binvox/*.binvox corpus/binvox/
rm -rf "$grids"
for format in obj ply gltf binvox; do
    cp seeds/"$format"/* "corpus/$format/"
    if [ -d "../tests/corpus/$format" ]; then
        cp ../tests/corpus/"$format"/* "corpus/$format/"
    fi
done
