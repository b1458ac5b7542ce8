#!/usr/bin/env bash
# Renders docs/gallery/*.png: four data sets, plain DVR beside three two-level
# method combinations each (scene descriptions in volumes/scenes/).
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release -q -p volgen -p raycaster-cli
volgen=target/release/volgen
rc=target/release/raycaster
work=target/gallery
out=docs/gallery
mkdir -p "$work" "$out"
$volgen generate -q --force --scene shapes --size 192 -o $work/shapes.vol
$volgen generate -q --force --scene shells --size 160 -o $work/shells.vol   # + shells.labels.vol
$volgen generate -q --force --scene noise --size 160 -o $work/noise.vol
$volgen generate -q --force --scene gradient --size 128 -o $work/gradient.vol
view="--size 200x200 --level 0 --force -q"
render() { $rc render "$@" $view; }
render $work/shapes.vol --tf shapes -o $out/shapes-dvr.png
for s in importance npr context; do
  render $work/shapes.vol --segments volumes/scenes/shapes-$s.toml -o $out/shapes-$s.png
done
render $work/shells.vol --tf shells -o $out/shells-dvr.png
for s in labels npr xray; do
  render $work/shells.vol --segments volumes/scenes/shells-$s.toml --labels $work/shells.labels.vol -o $out/shells-$s.png
done
render $work/noise.vol --tf cloud --zoom 1.5 -o $out/noise-dvr.png
for s in context npr importance; do
  render $work/noise.vol --zoom 1.5 --segments volumes/scenes/noise-$s.toml -o $out/noise-$s.png
done
render $work/gradient.vol --tf rainbow -o $out/gradient-dvr.png
for s in bands first-hit context; do
  render $work/gradient.vol --segments volumes/scenes/gradient-$s.toml -o $out/gradient-$s.png
done
echo "gallery written to $out"
