#!/usr/bin/env bash
# Runs every fuzz target for a short time (FUZZ_SECONDS each, default 20) when a
# nightly toolchain with cargo-fuzz is installed; otherwise says so and succeeds.
# CI calls it after the tests (.ci/run).
set -euo pipefail
cd "$(dirname "$0")/.."
SECONDS_EACH=${FUZZ_SECONDS:-20}
if ! cargo +nightly fuzz --version >/dev/null 2>&1; then
    echo "fuzz: skipped (needs a nightly toolchain and cargo-fuzz: cargo install cargo-fuzz)" >&2
    exit 0
fi
for target in $(cargo +nightly fuzz list); do
    echo "fuzz: $target for ${SECONDS_EACH} s" >&2
    cargo +nightly fuzz run "$target" -- -max_total_time="$SECONDS_EACH"
done
