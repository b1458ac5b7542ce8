#!/usr/bin/env bash
# The quality table of docs/benchmarks.md: renders a step-0.05 reference with
# today's renderer, then steps 0.25, 0.5 and 1.0 plain, jittered, pre-integrated
# and both, and prints each one's PSNR and largest channel difference against it.
#
#   docs/quality.sh NAME RENDER-ARGS...      (writes NAME-*.png into the current folder)
#   docs/quality.sh shapes --scene shapes --scene-size 128 --size 256
set -euo pipefail
R=${RAYCASTER:-raycaster}
name=$1; shift
$R render "$@" --step 0.05 -o $name-ref.png --force > /dev/null || exit 1
printf "%-8s %-6s %-22s %8s %6s %8s\n" scene step variant psnr_db max samples
for step in 0.25 0.5 1.0; do
  for v in "plain:" "jitter:--jitter" "pre:--preintegrate" "pre+jitter:--preintegrate --jitter"; do
    label=${v%%:*}; flags=${v#*:}
    out=$name-$step-$label.png
    samples=$($R render "$@" --step $step $flags -o $out --force --stats-json | python3 -c 'import json,sys; d=json.load(sys.stdin); print(d["samples"], round(d["seconds"],3))')
    c=$($R compare $out $name-ref.png --json)
    psnr=$(echo $c | python3 -c 'import json,sys; print(json.load(sys.stdin)["psnr_db"])')
    mx=$(echo $c | python3 -c 'import json,sys; print(json.load(sys.stdin)["max_difference"])')
    printf "%-8s %-6s %-22s %8.2f %6s %8s\n" $name $step $label $psnr $mx "$samples"
  done
done
