#!/usr/bin/env bash
# The proof that layertrace is a library a user can install and link: installs the build
# folder $1 into a temporary prefix, builds examples/ out of tree against it with
# find_package(layertrace), runs the three examples, and (for a static library) builds one of them
# again with nothing but pkg-config. Leaves nothing behind.
set -euo pipefail
build=$(cd "$1" && pwd)
src=$(cd "$(dirname "$0")/.." && pwd)
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
cmake --install "$build" --prefix "$tmp/prefix" >/dev/null
# The installed headers must stand alone: no include of a header that was not installed.
for h in $(cd "$tmp/prefix/include" && find layertrace -name '*.h'); do
  for inc in $(sed -n 's/^#include "\(layertrace\/[^"]*\)"/\1/p' "$tmp/prefix/include/$h"); do
    [ -f "$tmp/prefix/include/$inc" ] || { echo "installed $h includes $inc, which is not installed" >&2; exit 1; }
  done
done
# ... and compile alone with every warning an error, under GCC and Clang where they are here.
for cxx in g++ clang++-16; do
  command -v "$cxx" >/dev/null || continue
  for h in layertrace.h gpu.h; do
    [ -f "$tmp/prefix/include/layertrace/$h" ] || continue
    echo "#include <layertrace/$h>" | "$cxx" -std=c++20 -fsyntax-only -Wall -Wextra -Wpedantic -Werror -DGLM_FORCE_XYZW_ONLY \
      -DGLM_ENABLE_EXPERIMENTAL -I"$tmp/prefix/include" -x c++ - ||
      { echo "installed <layertrace/$h> does not compile alone with $cxx -Wall -Wextra -Werror" >&2; exit 1; }
  done
done
# The examples use the compiler the library was built with (the sanitizer runtimes must match).
compiler=$(sed -n "s/^CMAKE_CXX_COMPILER:[A-Z]*=//p" "$build/CMakeCache.txt")
cmake -S "$src/examples" -B "$tmp/examples" -DCMAKE_PREFIX_PATH="$tmp/prefix" -DCMAKE_BUILD_TYPE=Release ${compiler:+-DCMAKE_CXX_COMPILER="$compiler"} >/dev/null
cmake --build "$tmp/examples" -j 2 >/dev/null
mkdir -p "$tmp/out"
"$tmp/examples/trace_gbuffer" "$tmp/out/trace_gbuffer.png"
"$tmp/examples/classify_against_embree"
"$tmp/examples/custom_scene" "$tmp/out"
for f in trace_gbuffer.png custom_scene_hssr.png custom_scene_embree.png; do
  [ -s "$tmp/out/$f" ] || { echo "example output $f missing" >&2; exit 1; }
done
# The GPU example, where the library has its GPU part: one headless frame of HSSR reflections
# through layertrace/gpu.h, from the program's own draw call, must be the CLI's PNG of the same
# view, byte for byte (llvmpipe), on the default scene and on a fetched real scene. Not under the
# sanitizers: the GPU driver is not instrumented.
if [ -x "$tmp/examples/gpu_reflections" ] && [ -z "${LAYERTRACE_SANITIZED:-}" ]; then
  for scene in "$src/scenes/default.json" "$src/data/models/cornell_box.obj"; do
    [ -f "$scene" ] || continue
    "$tmp/examples/gpu_reflections" "$scene" "$tmp/out/example.png" 200 120 >/dev/null
    "$build/layertrace" render "$scene" --device gpu --tracer hssr --effect reflection --quiet --width 200 --height 120 -o "$tmp/out/cli.png"
    cmp -s "$tmp/out/example.png" "$tmp/out/cli.png" ||
      { echo "gpu_reflections $scene: its PNG is not the CLI's (render --device gpu --tracer hssr --effect reflection)" >&2; exit 1; }
    echo "test-install: gpu_reflections on $(basename "$scene") equals render --device gpu"
  done
fi
# The Python package, where the build has it: importable from the prefix's Debian location alone,
# and its examples run against it.
if [ -d "$tmp/prefix/lib/python3/dist-packages/layertrace" ]; then
  (cd "$tmp" && PYTHONPATH="$tmp/prefix/lib/python3/dist-packages" /usr/bin/python3 "$src/examples/python/render_and_compare.py" \
     "$src/scenes/default.json" "$tmp/out/py" >/dev/null)
  [ -s "$tmp/out/py/classes.png" ] || { echo "python example output classes.png missing" >&2; exit 1; }
  echo "test-install: Python package imported from lib/python3/dist-packages and its example run"
fi
libdir=$(dirname "$(find "$tmp/prefix" -name 'liblayertrace.*' | head -1)")
if [ -f "$libdir/liblayertrace.a" ]; then
  export PKG_CONFIG_PATH="$libdir/pkgconfig"
  # shellcheck disable=SC2046
  g++ -std=c++20 -O1 "$src/examples/classify_against_embree.cpp" -o "$tmp/pc_classify" $(pkg-config --cflags --static --libs layertrace)
  "$tmp/pc_classify" >/dev/null
  if [ -f "$tmp/prefix/include/layertrace/gpu.h" ]; then
    # shellcheck disable=SC2046
    g++ -std=c++20 -O1 "$src/examples/gpu_reflections/main.cpp" -o "$tmp/pc_gpu_reflections" $(pkg-config --cflags --static --libs layertrace epoxy)
    [ -n "${LAYERTRACE_SANITIZED:-}" ] || "$tmp/pc_gpu_reflections" "$src/scenes/default.json" "$tmp/out/pc.png" 64 36 >/dev/null
  fi
  echo "test-install: static library, CMake package and pkg-config: examples built and run"
else
  echo "test-install: shared library, CMake package: examples built and run"
fi
