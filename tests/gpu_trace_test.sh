#!/usr/bin/env bash
# The GPU frame's own accounting (bench --experiment frame, frame.json) against an independent
# count of the same run's OpenGL calls: apitrace traces the unchanged program through EGL, and
# tools/gl_frame_counts.py counts each "frame" debug group's links, allocations, bytes each way,
# host waits, dispatches and draws. Every frame must agree exactly, and the frames after the
# first must be a renderer's steady state: no link, no allocation, at most 64 KiB uploaded, one
# host wait. And render --device gpu must capture on the GPU: its trace has the draw calls.
# usage: gpu_trace_test.sh LAYERTRACE SOURCE_DIR
set -euo pipefail
LT="$1"
SRC="$2"
if [ -n "${LAYERTRACE_SANITIZED:-}" ]; then
  echo "gpu_trace_test: skipped in a sanitized build (the GPU driver is not instrumented)"
  exit 77
fi
if ! command -v apitrace >/dev/null; then
  echo "gpu_trace_test: apitrace is missing (scripts/install-deps.sh installs it)" >&2
  exit 1
fi
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
cd "$tmp"
apitrace trace --api egl -o frame.trace "$LT" bench "$SRC/scenes/default.json" --experiment frame --device gpu --frames 4 \
  --width 160 --height 90 -o out --quiet >trace.log 2>&1 || { cat trace.log >&2; exit 1; }
python3 "$SRC/tools/gl_frame_counts.py" frame.trace >counts.json
python3 - out/frame.json counts.json <<'PY'
import json, sys
own = json.load(open(sys.argv[1]))["frames"]
traced = json.load(open(sys.argv[2]))
keys = ("program_links", "buffer_allocations", "upload_bytes", "download_bytes", "host_waits", "dispatches", "draws")
assert len(own) == len(traced) == 4, f"{len(own)} frames in frame.json, {len(traced)} in the trace"
for i, (a, b) in enumerate(zip(own, traced)):
    for k in keys:
        assert a[k] == b[k], f"frame {i}: {k} is {a[k]} in frame.json but {b[k]} in the trace"
    if i == 0:
        assert a["program_links"] > 0 and a["buffer_allocations"] > 0, f"frame 0 links and allocates: {a}"
    else:
        assert a["program_links"] == 0 and a["buffer_allocations"] == 0, f"frame {i}: {a}"
        assert a["upload_bytes"] <= 64 * 1024 and a["host_waits"] <= 1 and a["draws"] >= 1, f"frame {i}: {a}"
print("gpu_trace_test: frame.json agrees with the trace on", len(own), "frames:", json.dumps({k: own[-1][k] for k in keys}))
PY
apitrace trace --api egl -o render.trace "$LT" render "$SRC/scenes/default.json" --device gpu --width 96 --height 64 -o r.png --quiet \
  >render.log 2>&1 || { cat render.log >&2; exit 1; }
draws="$(apitrace dump --color=never render.trace | grep -cE '^[0-9]+ glDraw' || true)"
if [ "$draws" -lt 1 ]; then
  echo "gpu_trace_test: render --device gpu issued no draw call: it did not capture on the GPU" >&2
  exit 1
fi
echo "gpu_trace_test: render --device gpu captured with $draws draw call(s)"
# Its frame is resident: the trace's one "frame" group agrees with render's own gpu.frame, waits
# once and reads back no more than the picture (96 × 64 pixels, RGBA8 for the PNG) and the
# counters.
python3 "$SRC/tools/gl_frame_counts.py" render.trace >render_counts.json
python3 - r.json render_counts.json <<'PY'
import json, sys
stats = json.load(open(sys.argv[1]))
own, traced = stats["gpu"]["frame"], json.load(open(sys.argv[2]))
keys = ("program_links", "buffer_allocations", "upload_bytes", "download_bytes", "host_waits", "dispatches", "draws")
assert stats["gpu"]["resident"] is True, "render --device gpu did not run as a resident frame"
assert len(traced) == 1, f"{len(traced)} frame groups in render's trace"
for k in keys:
    assert own[k] == traced[0][k], f"render: {k} is {own[k]} in its statistics but {traced[0][k]} in the trace"
assert own["host_waits"] == 1 and own["download_bytes"] <= 96 * 64 * 4 + 1024, own
print("gpu_trace_test: render's frame agrees with the trace:", json.dumps({k: own[k] for k in keys}))
PY
