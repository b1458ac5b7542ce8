#!/usr/bin/env bash
# Screenshot of the real viewer window with its Cut panel and slice views under
# Xvfb -> docs/images/viewer-slices.png. The built-in shapes scene is cut open by a
# session (crop box and clipping plane, restored into the Cut sliders).
#   docs/viewer-slices-screenshot.sh [OUT.png] [SESSION.toml]
# With a session, that session is shown instead (docs/sessions/lung1-cut.toml:
# the lung1 CT cut open -> docs/images/viewer-lung1-cut.png).
# Needs: xvfb (apt-get install xvfb) and python3; the framebuffer Xvfb keeps in a
# file (-fbdir, XWD format) is converted to PNG by the few lines of Python below.
# Uses the dev profile, the one CI builds Slint in (no second Slint build).
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build -q -p viewer
out=${1:-docs/images/viewer-slices.png}
session=${2:-}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
cat > "$tmp/cut.toml" <<'TOML'
# raycaster session (docs/viewer.md)
version = 1

[volume]
scene = "shapes"
size = 160
seed = 1

[image]
width = 922
height = 485

[camera]
target = [79.5, 79.5, 79.5]
distance = 290.0
azimuth_rad = 5.5
elevation_rad = 0.55
fov = 40.0

[transfer]
preset = "shapes"

[clip]
crop = [0.0, 0.0, 0.0, 159.0, 100.0, 159.0]
planes = [[79.5, 79.5, 100.0, 0.0, 0.0, -1.0]]
TOML
export SLINT_BACKEND=winit-software
Xvfb :97 -screen 0 1280x820x24 -fbdir "$tmp" -nolisten tcp &
xvfb=$!
sleep 2
[ -n "$session" ] || session=$tmp/cut.toml
DISPLAY=:97 "${CARGO_TARGET_DIR:-target}"/debug/viewer --session "$session" &
viewer=$!
sleep "${SETTLE:-15}"   # seconds for the frame to refine (more for a real scan)
python3 - "$tmp/Xvfb_screen0" "$out" <<'PY'
import struct, sys, zlib
data = open(sys.argv[1], "rb").read()
f = struct.unpack(">25I", data[:100])
header, width, height, order, bpp, stride, ncolors = f[0], f[4], f[5], f[7], f[11], f[12], f[19]
masks = f[14:17]
assert bpp == 32, bpp
pixels = data[header + 12 * ncolors:]
def channel(v, m):
    shift = (m & -m).bit_length() - 1
    return (v & m) >> shift
rows = []
for y in range(height):
    row = bytearray(b"\0")
    line = pixels[y * stride:y * stride + 4 * width]
    for x in range(width):
        v = int.from_bytes(line[4 * x:4 * x + 4], "little" if order == 0 else "big")
        row += bytes(channel(v, m) for m in masks)
    rows.append(bytes(row))
chunk = lambda t, d: struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d))
png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0))
png += chunk(b"IDAT", zlib.compress(b"".join(rows), 9)) + chunk(b"IEND", b"")
open(sys.argv[2], "wb").write(png)
PY
kill "$viewer" "$xvfb"
echo "wrote $out"
