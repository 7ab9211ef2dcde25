#!/usr/bin/env bash
# A check of the viewer, run under a virtual X server (xvfb-run, Mesa's software
# OpenGL): the scripted viewer's traced image equals `layertrace render` with the same camera
# and options (mean absolute difference ≤ 1/255 per channel), and its window screenshot is not
# blank (the picture and the panel are drawn); with --device gpu the picture is shown from the GPU
# without a read-back. $1 = the layertrace binary. Leaves nothing behind.
# Debian's python3 (with python3-matplotlib) reads the PNGs.
set -euo pipefail
bin=$1
src=$(cd "$(dirname "$0")/.." && pwd)
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
options=(--width 320 --height 180 --tracer hssr --effect reflection --bounces 2 --layers 3)
common=("${options[@]}" --quiet)
xvfb-run -a -s "-screen 0 1024x768x24" "$bin" view "$src/scenes/default.json" "${common[@]}" \
  --frames 3 -o "$tmp/view.png" --screenshot-ui "$tmp/ui.png"
"$bin" render "$src/scenes/default.json" "${common[@]}" -o "$tmp/render.png"
# GPU mode (a GL context sharing the window's objects): the same picture, read back for -o ...
xvfb-run -a -s "-screen 0 1024x768x24" "$bin" view "$src/scenes/default.json" "${common[@]}" --device gpu \
  --frames 3 -o "$tmp/view_gpu.png"
# ... and shown from the GPU where it was computed: the window alone (no panel) is render's
# picture, and the frame read back nothing but its counters.
shown=$(xvfb-run -a -s "-screen 0 1024x768x24" "$bin" view "$src/scenes/default.json" "${options[@]}" --device gpu \
  --frames 3 --hide-panel --screenshot-ui "$tmp/shown_gpu.png")
echo "$shown"
down=$(sed -n 's/.* \([0-9]*\) B down.*picture shown from the GPU.*/\1/p' <<<"$shown")
[ -n "$down" ] && [ "$down" -le 4096 ] || { echo "the GPU viewer did not show its picture from the GPU (${down:-no} bytes down)" >&2; exit 1; }
# A scripted screenshot without --frames is refused before any window opens (exit 2, no file).
if "$bin" view "$src/scenes/default.json" --screenshot "$tmp/bad.png" 2>/dev/null; then
  echo "view --screenshot without --frames was accepted" >&2; exit 1
fi
[ ! -e "$tmp/bad.png" ]
/usr/bin/python3 - "$tmp" <<'PY'
import sys
import matplotlib.image as mpimg
import numpy as np
d = sys.argv[1]
view, render, ui, gpu, shown = (mpimg.imread(f"{d}/{n}.png")[..., :3] for n in ("view", "render", "ui", "view_gpu", "shown_gpu"))
assert gpu.shape == render.shape and float(np.abs(gpu - render).mean()) <= 1.0 / 255.0, "the GPU viewer's image differs from render's"
assert shown.shape == render.shape and float(np.abs(shown - render).mean()) <= 1.0 / 255.0, "the window shown from the GPU differs from render's picture"
assert view.shape == render.shape == (180, 320, 3), (view.shape, render.shape)
mad = float(np.abs(view - render).mean())
print(f"viewer vs render: mean absolute difference {mad * 255:.4f}/255; ui {ui.shape[1]}x{ui.shape[0]}, std {ui.std():.3f}")
assert mad <= 1.0 / 255.0, "the viewer's traced image differs from render's"
assert render.std() > 0.02, "render's image is blank: the comparison would mean nothing"
assert ui.std() > 0.05 and len(np.unique(ui.reshape(-1, 3), axis=0)) > 50, "the window screenshot is blank"
PY
