#!/bin/sh
# How docs/view.png was made on a headless Debian machine: rerun's web viewer in
# Chromium under Xvfb, rendered by the software rasterizer (SwiftShader).
# Needs: apt-get install xvfb x11-apps chromium. Usage: sh docs/view_screenshot.sh OUT.png
set -eu
out=${1:-docs/view.png}
pipemap record --network paper -o /tmp/view_run.mcap --force
pipemap view /tmp/view_run.mcap --save /tmp/view_run.rrd --force
rerun --serve-web /tmp/view_run.rrd & web=$!
Xvfb :99 -screen 0 1600x1000x24 & xvfb=$!
sleep 5
DISPLAY=:99 chromium --no-sandbox --no-first-run --disable-dbus --use-gl=angle \
  --use-angle=swiftshader --enable-unsafe-swiftshader --ignore-gpu-blocklist \
  --window-size=1600,1000 --window-position=0,0 --kiosk \
  "http://127.0.0.1:9090?renderer=webgl&url=rerun%2Bhttp%3A%2F%2Flocalhost%3A9876%2Fproxy" \
  >/dev/null 2>&1 & browser=$!
sleep 60  # the viewer loads its wasm bundle and the recording
DISPLAY=:99 xwd -root -silent > /tmp/view.xwd
kill $browser $web $xvfb
python3 - "$out" <<'PY'
import struct, sys
import cv2, numpy as np
data = open("/tmp/view.xwd", "rb").read()
head = struct.unpack(">25I", data[:100])  # XWD header, big-endian
size, width, height, line, colours = head[0], head[4], head[5], head[12], head[19]
start = size + 12 * colours
pixels = np.frombuffer(data[start:start + line * height], np.uint8).reshape(height, line)
cv2.imwrite(sys.argv[1], pixels[:, : width * 4].reshape(height, width, 4)[:, :, :3])
PY
