#!/usr/bin/env bash
# Distributed rendering benchmark (docs/distributed.md): frame time, per-rank
# render and relay time and rank 0's gather time, for image sizes and rank
# counts, and the strong scaling of a 1024³ frame. Median of REPS runs each.
#
#   cargo build --release -p raycaster-cli -p volgen --features raycaster-cli/mpi
#   docs/bench/distributed.sh [OUT_DIR]      # writes OUT_DIR/distributed.csv
#
# Volumes go to $BENCH_DIR (default /tmp/raycaster-bench; 1.1 GB).
set -euo pipefail
cd "$(dirname "$0")/../.."
OUT=${1:-docs/bench}
DIR=${BENCH_DIR:-/tmp/raycaster-bench}
REPS=${REPS:-5}
RAYCASTER=target/release/raycaster
VOLGEN=target/release/volgen
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
mkdir -p "$DIR" "$OUT"
[ -f "$DIR/shapes-256.vol" ] || $VOLGEN generate --scene shapes --size 256 -o "$DIR/shapes-256.vol" --quiet
[ -f "$DIR/shapes-1024.vol" ] || $VOLGEN generate --scene shapes --size 1024 -o "$DIR/shapes-1024.vol" --quiet

CSV="$OUT/distributed.csv"
echo "case,compositing,volume,image,ranks,threads_per_rank,rep,frame_s,render_s_max,relay_s_max,relay_s_mean,gather_s,samples" > "$CSV"

# One run: prints a CSV row from the --stats-json object.
run() { # case compositing volume size ranks threads rep
    local json
    if [ "$5" = 0 ]; then # single process, no MPI
        json=$($RAYCASTER render "$DIR/$3" --size "$4" --threads "$6" -o "$DIR/out.png" --force --quiet --stats-json)
    else
        json=$(mpirun --oversubscribe -np "$5" $RAYCASTER render "$DIR/$3" --distributed --compositing "$2" \
            --size "$4" --threads "$6" -o "$DIR/out.png" --force --quiet --stats-json)
    fi
    python3 - "$1" "$2" "$3" "$4" "$5" "$6" "$7" "$json" >> "$CSV" <<'PY'
import json, sys
case, compositing, volume, size, ranks, threads, rep, text = sys.argv[1:]
s = json.loads(text)
ranks_ = s.get("ranks", [])
render = max((r["render_seconds"] for r in ranks_), default=s["seconds"])
relay = [r["relay_seconds"] for r in ranks_] or [0.0]
print(",".join(map(str, [case, compositing, volume, size, ranks, threads, rep, s["seconds"], render,
    max(relay), sum(relay) / len(relay), s.get("gather_seconds", 0.0), s["samples"]])))
PY
}

for rep in $(seq "$REPS"); do
    # Compositing cost against image size and rank count (256³, one thread per
    # rank), the relay against direct send of partial images.
    for size in 256 512 1024 2048; do
        run image single shapes-256.vol "$size" 0 1 "$rep"
        for ranks in 1 2 4 8; do
            for compositing in relay direct-send; do
                run image "$compositing" shapes-256.vol "$size" "$ranks" 1 "$rep"
            done
        done
    done
    # Strong scaling of a 1024³ frame, 700², on this machine's cores.
    run scaling single shapes-1024.vol 700 0 1 "$rep"
    run scaling single shapes-1024.vol 700 0 2 "$rep"
    for compositing in relay direct-send; do
        run scaling "$compositing" shapes-1024.vol 700 1 1 "$rep"
        run scaling "$compositing" shapes-1024.vol 700 2 1 "$rep"
    done
done
echo "wrote $CSV"
