#!/usr/bin/env bash
# Screenshot of the real viewer window under Xvfb -> docs/images/viewer.png.
# Needs: xvfb xauth imagemagick (apt-get install xvfb xauth imagemagick).
# Uses the dev profile, the one CI builds Slint in (no second Slint build).
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build -q -p viewer
out=${1:-docs/images/viewer.png}
export SLINT_BACKEND=winit-software
xvfb-run -a -s "-screen 0 1280x820x24" bash -c '
  target/debug/viewer --segments volumes/scenes/shapes-importance.toml &
  pid=$!
  sleep 12
  import -window root "$0"
  kill $pid
' "$out"
echo "wrote $out"
