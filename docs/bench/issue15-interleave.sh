#!/bin/bash
# Issue 15's before/after criterion comparison (docs/benchmarks.md, "Issue 15"):
# the bench binaries of two commits, run interleaved on a loaded machine. Before and
# after run back to back per chunk of benchmark ids (one optimisations or two-level id,
# or one brick side × {seq, t1, t2} of the parallel group), the order alternating per
# chunk and per round; each (round, commit) gets its own CRITERION_HOME.
#
#   git worktree add --detach $BEFORE 60ba035 ; git worktree add --detach $AFTER e8e8c81
#   (cd $BEFORE && CARGO_TARGET_DIR=$BEFORE_TARGET nice -n 5 cargo bench -p raycaster-benches --no-run)
#   (cd $AFTER && CARGO_TARGET_DIR=$AFTER_TARGET nice -n 5 cargo bench -p raycaster-benches --no-run)
#   OUT=... docs/bench/issue15-interleave.sh 1 2 3
#
# Results: $OUT/crit/r<round>-<before|after>/<group>/<id>/new/{estimates,sample}.json
set -u
BEFORE=${BEFORE:-/work/wt-before}; AFTER=${AFTER:-/work/wt-after}
BEFORE_TARGET=${BEFORE_TARGET:-/work/target-before}; AFTER_TARGET=${AFTER_TARGET:-/work/target-after}
OUT=${OUT:-/work/benchlog}
bin() { ls "$1"/release/deps/"$2"-* | grep -v '\.d$' | head -1; }
CHUNKS=(
 "optimisations|/none/.*-dvr-256x256\$"
 "optimisations|/ert/"
 "optimisations|/ess/"
 "optimisations|/both/"
 "optimisations|unshaded"
)
for b in 8 16 32; do for r in seq t1 t2; do
  if [ $r = seq ]; then CHUNKS+=("parallel|/seq-brick$b/"); else CHUNKS+=("parallel|/$r-tile[0-9]+-brick$b/"); fi
done; done
CHUNKS+=("two_level|^two-level/plain-dvr\$" "two_level|^two-level/10-layers-dvr\$")
mkdir -p "$OUT/logs"
for r in "$@"; do
  k=0
  for c in "${CHUNKS[@]}"; do
    g=${c%%|*}; f=${c#*|}
    if (( (r + k) % 2 == 1 )); then order="before after"; else order="after before"; fi
    for w in $order; do
      if [ $w = before ]; then dir=$BEFORE; exe=$(bin "$BEFORE_TARGET" $g); else dir=$AFTER; exe=$(bin "$AFTER_TARGET" $g); fi
      export CRITERION_HOME=$OUT/crit/r$r-$w
      mkdir -p "$CRITERION_HOME"
      log=$OUT/logs/r$r-$w.log
      echo "# round $r $w $g '$f' start $(date -Is) load $(cut -d' ' -f1-3 /proc/loadavg)" >> "$log"
      ( cd "$dir" && nice -n 5 "$exe" --bench --noplot --warm-up-time 2 --measurement-time 4 "$f" ) >> "$log" 2>&1
      echo "# end $(date -Is) rc $? load $(cut -d' ' -f1-3 /proc/loadavg)" >> "$log"
    done
    echo "r$r chunk $k $g $f done $(date +%T) load $(cut -d' ' -f1-3 /proc/loadavg)" >> "$OUT/progress"
    k=$((k+1))
  done
done
