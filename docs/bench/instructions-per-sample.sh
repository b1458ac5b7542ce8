#!/usr/bin/env bash
# Issue 16's measure of the marching kernel: instructions per sample, counted by
# callgrind (the load on the machine does not move it).
#
#   (instructions of a 256×256 frame − instructions of a 32×32 frame)
#     ÷ (the difference of their samples)
#
# of `raycaster render --scene shapes --scene-size 128 --threads 1` (shaded DVR,
# ERT and ESS on, step 0.5 unless given). Extra arguments go to both renders, e.g.
#
#   docs/bench/instructions-per-sample.sh                 # the issue's figure
#   docs/bench/instructions-per-sample.sh --step 0.2
#   docs/bench/instructions-per-sample.sh --simd scalar   # the reference kernel
#
# The binary is $RAYCASTER, else `raycaster` on the PATH (a release build:
# `cargo build --release -p raycaster-cli`). Valgrind does not run AVX-512 code:
# the automatic kernel level is AVX2 or lower on the machines it counts on, and
# `--simd avx512` cannot be counted. Set KEEP=DIR to keep the callgrind files
# (then `callgrind_annotate --inclusive=no DIR/cg.256` shows where they go).
set -euo pipefail

bin=${RAYCASTER:-raycaster}
if ! command -v "$bin" >/dev/null 2>&1; then
    echo "error: no raycaster binary: build one (cargo build --release -p raycaster-cli)" \
        "and put it on the PATH or name it in RAYCASTER" >&2
    exit 2
fi
if ! command -v valgrind >/dev/null 2>&1; then
    echo "error: valgrind is not installed (Debian: apt-get install valgrind)" >&2
    exit 2
fi
args=("$@")
has_step=0
for a in "${args[@]+"${args[@]}"}"; do
    [[ $a == --step || $a == --step=* ]] && has_step=1
done
[ "$has_step" = 1 ] || args+=(--step 0.5)

dir=${KEEP:-$(mktemp -d)}
mkdir -p "$dir"
[ -n "${KEEP:-}" ] || trap 'rm -rf "$dir"' EXIT

declare -A instructions samples
for size in 32 256; do
    echo "callgrind: ${size}x$size frame ..." >&2
    if ! valgrind --tool=callgrind --callgrind-out-file="$dir/cg.$size" \
        "$bin" render --scene shapes --scene-size 128 --size "${size}x$size" --threads 1 \
        --stats-json --force -o "$dir/frame-$size.png" "${args[@]}" \
        >"$dir/stats-$size.json" 2>"$dir/valgrind-$size.log"; then
        # (The render's own error is in valgrind's log, among valgrind's lines.)
        grep -v '^==[0-9]*==' "$dir/valgrind-$size.log" >&2 || true
        echo "error: the ${size}x$size render failed under valgrind" >&2
        exit 1
    fi
    instructions[$size]=$(awk '/^(summary|totals):/ { print $2; exit }' "$dir/cg.$size")
    samples[$size]=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["samples"])' \
        "$dir/stats-$size.json")
done

python3 - "${instructions[32]}" "${instructions[256]}" "${samples[32]}" "${samples[256]}" <<'EOF'
import sys
i32, i256, s32, s256 = map(int, sys.argv[1:])
if s256 <= s32:
    sys.exit("error: the 256x256 frame took no more samples than the 32x32 one")
print(f"instructions: {i32} (32x32), {i256} (256x256)")
print(f"samples:      {s32} (32x32), {s256} (256x256)")
print(f"instructions per sample: {(i256 - i32) / (s256 - s32):.1f}")
EOF
