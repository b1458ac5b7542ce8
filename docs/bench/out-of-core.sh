#!/usr/bin/env bash
# The out-of-core measurements of docs/performance.md ("Volumes larger than RAM"):
# time to the first picture and to a full-resolution frame from a cold page cache,
# bytes read, and the peak anonymous memory (RssAnon) of the renderer.
#
#   docs/bench/out-of-core.sh FILE [RAYCASTER]
#
# Needs root (it drops the page cache before each cold run: `echo 3 >
# /proc/sys/vm/drop_caches`). FILE: e.g. `volgen generate --size 3072 --layout
# bricked --no-labels -o big.vol` (35 GB; its pyramid is embedded, or added by
# `volgen pyramid big.vol`).
set -euo pipefail
file=${1:?usage: out-of-core.sh FILE [RAYCASTER]}
raycaster=${2:-target/release/raycaster}

drop_cache() { sync; echo 3 > /proc/sys/vm/drop_caches; }

# Runs "$@", prints its wall time and the peak RssAnon (and RssFile) sampled every
# millisecond (peak-anon.py beside this script).
measure() {
    "$(dirname "$0")/peak-anon.py" "$@"
}

run() {
    local name=$1; shift
    echo "== $name: raycaster render $file $*"
    measure "$raycaster" render "$file" -o /tmp/out-of-core.png --force -q --stats "$@" 2>&1 \
        | grep -E 'level|read from disk|bricks|time|samples taken|wall' || true
}

drop_cache; run "first picture, cold cache" --size 512x512 --level auto
drop_cache; run "full resolution, cold cache" --size 700x700 --level 0
run "full resolution, warm cache" --size 700x700 --level 0
