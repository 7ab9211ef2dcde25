#!/usr/bin/env bash
# Installs everything layertrace needs on Debian 12, non-interactively and idempotently.
# Starts from a minimal Debian 12 that has only git and make. Uses sudo when not root.
set -euo pipefail

# `--run`: only what building and running the CLI needs (`make run`); without it also the
# tests, benchmarks, fuzzers (clang), scene fetching and plots (`make test`).
packages=(
  build-essential cmake pkg-config ca-certificates
  libembree-dev libassimp-dev libtbb-dev libglm-dev libcli11-dev nlohmann-json3-dev
  libopenexr-dev libstb-dev zlib1g-dev libhwy-dev
  # The GPU back end: OpenGL through headless EGL (libepoxy), shaders checked at build time, and
  # Mesa's drivers (llvmpipe runs it on a machine without a GPU).
  libepoxy-dev libegl-dev glslang-tools libegl-mesa0 libgl1-mesa-dri
)
if [ "${1:-}" != "--run" ]; then
  packages+=(libgtest-dev libbenchmark-dev python3 python3-matplotlib unzip zip clang-16 libclang-rt-16-dev)
  # An independent count of what a GPU frame asks of the driver (tests/gpu_trace_test.sh).
  packages+=(apitrace)
  # The vector loops compiled for aarch64 (scripts/cross-aarch64.sh).
  packages+=(g++-aarch64-linux-gnu)
  # The viewer (`layertrace view`) and its test under a virtual X server with Mesa's software GL.
  packages+=(libglfw3-dev libimgui-dev xvfb xauth)
  # The Python package (docs/python.md) and its tests, sweeps on Dask distributed included.
  packages+=(python3-dev pybind11-dev python3-numpy python3-pandas python3-pytest python3-distributed)
fi
# No npm: the default scene's small bunny is committed as an OBJ (scenes/default/bunny.obj).

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present"
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
