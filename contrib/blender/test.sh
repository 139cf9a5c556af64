#!/usr/bin/env bash
# Checks the Blender add-on (voltrack_import.py) headless on the bending-bar
# fixture's GLB and PC2, and on the parting fixture's (a ball leaving a slab:
# two segments in one mesh, the stretch not shown shrunk onto a point):
# scene frame rate and range, shape keys, object name, and every capture's
# vertices at its scene frame (check_import.py).
# Skips (exit 0) when `blender` is not on PATH. VOLTRACK names the binary
# (default target/release/voltrack, built if missing).
set -euo pipefail
cd "$(dirname "$0")/../.."
if ! command -v blender >/dev/null 2>&1; then
    echo "contrib/blender/test.sh: blender not on PATH, add-on check skipped"
    exit 0
fi
voltrack=${VOLTRACK:-target/release/voltrack}
if [ ! -x "$voltrack" ]; then
    cargo build --release --quiet
fi
out=target/ci/blender
mkdir -p "$out"
for ext in glb gltf pc2; do
    "$voltrack" convert fixtures/bending_bar -r 48 -n 120 --fps 29.97 -o "$out/bar.$ext" >/dev/null
done
"$voltrack" convert fixtures/bending_bar -r 48 -n 120 -o "$out/bar30.glb" >/dev/null
"$voltrack" convert fixtures/bending_bar -r 48 -n 120 --compress -o "$out/bar_compress.glb" >/dev/null
for ext in glb pc2; do
    "$voltrack" convert fixtures/parting -r 48 -n 150 -o "$out/parting.$ext" --json >"$out/parting.$ext.json"
    python3 -c 'import json, sys; sys.exit(len(json.load(open(sys.argv[1]))["segments"]) < 2)' "$out/parting.$ext.json" \
        || { echo "FAIL: fixtures/parting was not converted as segments" >&2; exit 1; }
done
blender --version | head -n 1
run() { blender -b --factory-startup --python-exit-code 1 --python "$@" 2>&1; }
# The headless command the README gives prints one JSON line per import.
for f in "$out/bar.glb" "$out/bar.pc2"; do
    line=$(run contrib/blender/voltrack_import.py -- "$f" --empty | grep '^{"file"') \
        || { echo "FAIL: no summary from voltrack_import.py on $f" >&2; exit 1; }
    echo "$line"
done
# The checks: at Blender's 24 fps default the captures would fall between frames.
log=$(mktemp)
trap 'rm -f "$log"' EXIT
status=0
run contrib/blender/check_import.py -- "$out/bar.glb" "$out/bar.gltf" "$out/bar.pc2" "$out/bar30.glb" --expect-name bending_bar >"$log" || status=$?
run contrib/blender/check_import.py -- "$out/bar.glb" "$out/bar.pc2" --frame-start 1 --operator --expect-name bending_bar >>"$log" || status=$?
run contrib/blender/check_import.py -- "$out/parting.glb" "$out/parting.pc2" --expect-name parting >>"$log" || status=$?
# A --compress file: imported where the importer reads EXT_meshopt_compression,
# else refused before the scene is touched.
reads_meshopt='import sys; sys.path.insert(0, "contrib/blender"); import voltrack_import as v; sys.exit(0 if "EXT_meshopt_compression" in (v.importer_extensions() or ()) else 3)'
if blender -b --factory-startup --python-exit-code 1 --python-expr "$reads_meshopt" >/dev/null 2>&1; then
    run contrib/blender/check_import.py -- "$out/bar_compress.glb" >>"$log" || status=$?
else
    run contrib/blender/check_import.py -- "$out/bar_compress.glb" --refused >>"$log" || status=$?
fi
grep -E '^(PASS|FAIL)' "$log" || true
if [ "$status" -ne 0 ] || grep -q '^FAIL' "$log" || [ "$(grep -c '^PASS' "$log")" -ne 9 ]; then
    echo "contrib/blender/test.sh: FAILED" >&2
    cat "$log" >&2
    exit 1
fi
echo "contrib/blender/test.sh: 9 imports checked"
