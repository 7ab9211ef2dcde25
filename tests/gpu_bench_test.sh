#!/usr/bin/env bash
# scripts/gpu-bench.sh at one small size: it must run every experiment on every scene and write
# the JSON and the Markdown with a row per tracer and per k; without a device, one line and 2.
#   tests/gpu_bench_test.sh LAYERTRACE_BINARY SOURCE_DIR WORK_DIR
set -uo pipefail
bin=$1 src=$2 work=$3
rm -rf "$work"
export LAYERTRACE_BIN=$bin GPU_BENCH_SIZES=64x36 GPU_BENCH_FRAMES=3 GPU_BENCH_REPEAT=1
"$src/scripts/gpu-bench.sh" "$work/out" || { echo "FAIL: gpu-bench.sh exited $?"; exit 1; }
md="$work/out/gpu-bench.md"
rows=$(grep -c '^| gpu | hssr |' "$md")
[ "$rows" -eq 6 ] || { echo "FAIL: $rows hssr rows (want 2 per scene, 3 scenes)"; exit 1; }
peel=$(awk '/^## /{inpeel = /-peel$/} inpeel && /^\| [1-8] \|/' "$md" | wc -l)
[ "$peel" -eq 24 ] || { echo "FAIL: $peel peel rows (want k = 1..8 for 3 scenes)"; exit 1; }
grep -q '"experiment": "peel"' "$work/out/gpu-bench.json" || { echo "FAIL: no peel run in the JSON"; exit 1; }
frames=$(grep -c '^summary (median' "$md")
[ "$frames" -eq 3 ] || { echo "FAIL: $frames frame summaries (want one per scene)"; exit 1; }
for t in quadtree ldc grid hybrid; do
  n=$(grep -c "^| gpu | $t |" "$md")
  [ "$n" -eq 3 ] || { echo "FAIL: $n $t rows (want one per scene)"; exit 1; }
done
geo=$(grep -c '^| grid_gpu |' "$md")
[ "$geo" -eq 3 ] || { echo "FAIL: $geo GPU grid rows (want one per scene)"; exit 1; }
built=$(grep -c '^| GPU (GPU ms; ' "$md")
[ "$built" -eq 3 ] || { echo "FAIL: $built GPU grid builds (want one per scene)"; exit 1; }
same=$(grep -c '^| CPU (same cells: True) |' "$md")
[ "$same" -eq 3 ] || { echo "FAIL: the GPU built other cells than the CPU in $((3 - same)) scenes"; exit 1; }
err=$(__EGL_VENDOR_LIBRARY_FILENAMES=/nonexistent.json "$src/scripts/gpu-bench.sh" "$work/none" 2>&1 >/dev/null)
status=$?
[ $status -eq 2 ] || { echo "FAIL: without a device the status is $status"; exit 1; }
[ "$(printf '%s\n' "$err" | wc -l)" -eq 1 ] || { echo "FAIL: without a device: $err"; exit 1; }
echo "ok: $rows hssr rows, $peel peel rows, $frames frame runs, $geo GPU grid runs; without a device: $err"
