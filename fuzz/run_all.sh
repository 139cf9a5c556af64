#!/usr/bin/env bash
# Runs every target for $1 seconds (default 300), one job each, in turn.
set -uo pipefail
cd "$(dirname "$0")"
secs=${1:-300}
mkdir -p artifacts
for t in obj ply gltf binvox; do
    cargo +nightly fuzz run "$t" ${FUZZ_TARGET_DIR:+--target-dir "$FUZZ_TARGET_DIR"} -- \
        -max_total_time="$secs" -rss_limit_mb=2048 -timeout=10 -dict=dicts/"$t".dict -print_final_stats=1 \
        > "artifacts/$t.log" 2>&1
    echo "$t: exit $?"
done
