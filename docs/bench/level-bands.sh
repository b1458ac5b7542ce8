#!/usr/bin/env bash
# The "Levels by depth" measurements of docs/performance.md: deep perspective
# frames of a large bricked file from a cold page cache, one level for the whole
# frame (an older build's `--level auto`, or `--level 0`) against a level per band
# of depths (`--level auto` now): frame time, bytes read, samples.
#
#   docs/bench/level-bands.sh FILE [RAYCASTER] [OLD_RAYCASTER]
#
# Needs root (drops the page cache before each run). FILE: e.g. `volgen generate
# --size 2048 --layout bricked --no-labels -o b2048.vol` (12.1 GB with its pyramid).
set -euo pipefail
file=${1:?usage: level-bands.sh FILE [RAYCASTER] [OLD_RAYCASTER]}
raycaster=${2:-target/release/raycaster}
old=${3:-}

drop_cache() { sync; echo 3 > /proc/sys/vm/drop_caches; }

run() {
    local binary=$1 name=$2; shift 2
    drop_cache
    local start end
    start=$(date +%s.%N)
    "$binary" render "$file" -o /tmp/level-bands.png --force -q --stats-json "$@" \
        | python3 -c "import json, sys; d = json.load(sys.stdin); print('$name', *('%s=%s' % (k, d.get(k)) for k in ('level', 'coarsest_level', 'samples', 'bytes_read', 'seconds')))"
    end=$(date +%s.%N)
    echo "  whole process $(echo "$end - $start" | bc) s"
}

for view in "--fov 90 --zoom 2" "--fov 90 --zoom 8"; do
    echo "== $view, 700x700"
    # shellcheck disable=SC2086
    run "$raycaster" "bands (auto)" --size 700x700 $view
    # shellcheck disable=SC2086
    run "$raycaster" "level 0" --size 700x700 $view --level 0
    if [ -n "$old" ]; then
        # shellcheck disable=SC2086
        run "$old" "older build, auto (one level)" --size 700x700 $view
    fi
done
