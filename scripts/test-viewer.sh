#!/usr/bin/env bash
# A check of the viewer, run under a virtual X server (xvfb-run, Mesa's software
# OpenGL): the scripted viewer's traced image equals `layertrace render` with the same camera
# and options (mean absolute difference ≤ 1/255 per channel), and its window screenshot is not
# blank (the picture and the panel are drawn). $1 = the layertrace binary. Leaves nothing behind.
# Debian's python3 (with python3-matplotlib) reads the PNGs.
set -euo pipefail
bin=$1
src=$(cd "$(dirname "$0")/.." && pwd)
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
common=(--width 320 --height 180 --tracer hssr --effect reflection --bounces 2 --layers 3 --quiet)
xvfb-run -a -s "-screen 0 1024x768x24" "$bin" view "$src/scenes/default.json" "${common[@]}" \
  --frames 3 -o "$tmp/view.png" --screenshot-ui "$tmp/ui.png"
"$bin" render "$src/scenes/default.json" "${common[@]}" -o "$tmp/render.png"
# GPU mode (the headless GL context beside the window's): the same picture.
xvfb-run -a -s "-screen 0 1024x768x24" "$bin" view "$src/scenes/default.json" "${common[@]}" --device gpu \
  --frames 3 -o "$tmp/view_gpu.png"
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
view, render, ui, gpu = (mpimg.imread(f"{d}/{n}.png")[..., :3] for n in ("view", "render", "ui", "view_gpu"))
assert gpu.shape == render.shape and float(np.abs(gpu - render).mean()) <= 1.0 / 255.0, "the GPU viewer's image differs from render's"
assert view.shape == render.shape == (180, 320, 3), (view.shape, render.shape)
mad = float(np.abs(view - render).mean())
print(f"viewer vs render: mean absolute difference {mad * 255:.4f}/255; ui {ui.shape[1]}x{ui.shape[0]}, std {ui.std():.3f}")
assert mad <= 1.0 / 255.0, "the viewer's traced image differs from render's"
assert render.std() > 0.02, "render's image is blank: the comparison would mean nothing"
assert ui.std() > 0.05 and len(np.unique(ui.reshape(-1, 3), axis=0)) > 50, "the window screenshot is blank"
PY
