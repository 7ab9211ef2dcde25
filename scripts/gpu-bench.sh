#!/usr/bin/env bash
# The GPU benchmark, prepared for a machine with an NVIDIA (or any OpenGL 4.5) driver and no
# display, compiler or network. Run it from a bundle made by `make gpu-bundle` (or from a built
# tree). It writes OUT/gpu-bench.json and OUT/gpu-bench.md:
#   - every stage (raster, sort, hierarchy, trace, shade; GL timer queries) of ssr (stride 1 and 4),
#     ssr-layers, hiz, hssr, the quad-tree (built and traced on the GPU, beside HSSR), the layered
#     depth cube, the grid and the hybrid (traced on the GPU) and hssr with persistent threads, with
#     plain Embree on the CPU over the same rays (trace_vs_embree), iterations per ray and memory,
#     at 1280×720, 1920×1080 and 3840×2160, k = 4,
#     on the default scene and two fetched real scenes;
#   - per-pixel lists against depth peeling for k = 1…8 at 1280×720 (Hofmann et al. 2017, Fig. 8);
#   - the irregular grid walked on the GPU (geobench --device gpu at the first size): MRays/s of
#     primary, AO and diffuse rays against plain Embree on the CPU and the grid on the CPU, for
#     the CPU's structure uploaded (grid_gpu) and for the grid built on the GPU (grid_gpu_build:
#     its build's GPU milliseconds by step, cells, references and memory beside the CPU build's);
#   - the resident frame (bench --experiment frame): GPU_BENCH_FRAMES (default 30) frames of HSSR
#     reflections along an orbit at each size, wall against GPU milliseconds per frame, and what
#     each frame moved over the bus and waited for.
# Without an OpenGL 4.5 device it prints one line and exits with status 2.
#   scripts/gpu-bench.sh [OUT_DIR]        (default: gpu-bench-out)
# GPU_BENCH_SIZES="W1xH1 …" replaces the three sizes (the first one also sizes the peel runs),
# e.g. for a smoke test on a machine without a GPU; GPU_BENCH_REPEAT (default 5) the timed
# repeats of stages, geobench and peel.
set -uo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
out=${1:-gpu-bench-out}
if [ -n "${LAYERTRACE_BIN:-}" ]; then bin=$LAYERTRACE_BIN; elif [ -x "$here/layertrace" ]; then bin="$here/layertrace"; else bin="$here/build/layertrace"; fi
[ -d "$here/lib" ] && export LD_LIBRARY_PATH="$here/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
# A driver whose EGL vendor file is outside glvnd's search path (NVIDIA containers).
if [ -z "${__EGL_VENDOR_LIBRARY_FILENAMES:-}" ] && [ -f /usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json ] &&
   [ ! -d /usr/share/glvnd/egl_vendor.d ]; then
  export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
fi
mkdir -p "$out"
probe=$("$bin" render "$here/scenes/default.json" --device gpu --width 64 --height 36 --quiet -o "$out/probe.png" 2>&1)
if [ $? -ne 0 ]; then
  echo "gpu-bench: ${probe#layertrace: }" >&2
  exit 2
fi
sizes=${GPU_BENCH_SIZES:-"1280x720 1920x1080 3840x2160"}
repeat=${GPU_BENCH_REPEAT:-5}
first=${sizes%% *}
start=$SECONDS
runs=()
geo=()
for scene in default fzk-haus am-thornish; do
  for size in $sizes; do
    dir="$out/$scene-$size"
    "$bin" bench "$here/scenes/$scene.json" --experiment stages --device gpu --repeat "$repeat" --layers 4 \
        --width "${size%x*}" --height "${size#*x}" --quiet -o "$dir" || { echo "gpu-bench: $scene $size failed" >&2; exit 1; }
    runs+=("$dir/stages.json")
    dir="$out/$scene-frame-$size"
    "$bin" bench "$here/scenes/$scene.json" --experiment frame --device gpu --frames "${GPU_BENCH_FRAMES:-30}" --layers 4 \
        --width "${size%x*}" --height "${size#*x}" --quiet -o "$dir" || { echo "gpu-bench: $scene frame $size failed" >&2; exit 1; }
    runs+=("$dir/frame.json")
  done
  dir="$out/$scene-geobench"
  "$bin" geobench "$here/scenes/$scene.json" --device gpu --repeat "$repeat" --width "${first%x*}" --height "${first#*x}" --quiet -o "$dir" ||
      { echo "gpu-bench: $scene geobench failed" >&2; exit 1; }
  geo+=("$dir/geobench.json")
  dir="$out/$scene-peel"
  "$bin" bench "$here/scenes/$scene.json" --experiment peel --device gpu --repeat "$repeat" --width "${first%x*}" --height "${first#*x}" --quiet -o "$dir" ||
      { echo "gpu-bench: $scene peel failed" >&2; exit 1; }
  runs+=("$dir/peel.json")
done
# One JSON (every run's statistics) and one Markdown table per experiment.
{
  echo "["
  first=1
  for f in "${runs[@]}" "${geo[@]}"; do [ $first -eq 1 ] || echo ","; first=0; cat "$f"; done
  echo "]"
} > "$out/gpu-bench.json"
{
  echo "# layertrace GPU benchmark"
  echo
  renderer=$(grep -o '"gpu_renderer": "[^"]*"' "${runs[0]}" | head -1 | cut -d'"' -f4)
  driver=$(grep -o '"version": "[^"]*"' "${runs[0]}" | head -1 | cut -d'"' -f4)
  echo "$("$bin" --version | head -1); GPU: $renderer; driver: $driver; CPU: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ //'); $(date -u +%Y-%m-%d); $((SECONDS - start)) s"
  for f in "${runs[@]}"; do
    echo
    echo "## $(basename "$(dirname "$f")")"
    echo
    csv="${f%.json}.csv"
    head -1 "$csv" | sed 's/^/| /; s/,/ | /g; s/$/ |/'
    head -1 "$csv" | sed 's/[^,]*/---/g; s/^/| /; s/,/ | /g; s/$/ |/'
    tail -n +2 "$csv" | sed 's/^/| /; s/,/ | /g; s/$/ |/'
    case "$f" in
      */frame.json)
        echo
        echo "summary (median of the frames after the first): $(python3 -c 'import json,sys; print(json.dumps(json.load(open(sys.argv[1]))["summary"]))' "$f" 2>/dev/null || grep -o '"summary": {[^}]*}' "$f")"
        ;;
    esac
  done
  # The grid on the GPU (the CPU's structure uploaded, and the grid built on the GPU) against
  # Embree and the grid on the CPU.
  for f in "${geo[@]}"; do
    echo
    echo "## $(basename "$(dirname "$f")")"
    echo
    python3 - "$f" <<'PY' 2>/dev/null || grep -o '"grid_gpu": {[^}]*}' "$f"
import json, sys
g = json.load(open(sys.argv[1]))["geobench"]
print("| tracer | build ms | MiB | MRays/s primary | ao | diffuse | agreement with plain Embree (worst) |")
print("|---|---|---|---|---|---|---|")
for t in ("embree", "grid", "grid_gpu", "grid_gpu_build"):
    r = g[t]
    worst = min(r["agreement_" + s] for s in ("primary", "ao", "diffuse"))
    print(f"| {t} | {r['build_ms']:.1f} | {r['memory_bytes'] / 1048576:.1f} | {r['mrays_primary']:.2f} | {r['mrays_ao']:.2f} | {r['mrays_diffuse']:.2f} | {worst:.6f} |")
b = g["grid_gpu_build"]
print()
print("| grid build | ms | cells | references | MiB |")
print("|---|---|---|---|---|")
steps = ", ".join(f"{k} {v:.1f}" for k, v in b["build_ms_by_step"].items())
print(f"| GPU (GPU ms; {steps}) | {b['build_ms']:.1f} | {b['cells']} | {b['references']} | {b['memory_bytes'] / 1048576:.1f} |")
c = b["cpu_twin"]
print(f"| CPU (same cells: {c['same_cells']}) | {c['build_ms']:.1f} | {c['cells']} | {c['references']} | {c['memory_bytes'] / 1048576:.1f} |")
PY
  done
} > "$out/gpu-bench.md"
echo "gpu-bench: wrote $out/gpu-bench.json and $out/gpu-bench.md in $((SECONDS - start)) s"
