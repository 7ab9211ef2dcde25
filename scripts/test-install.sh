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
  echo "test-install: static library, CMake package and pkg-config: examples built and run"
else
  echo "test-install: shared library, CMake package: examples built and run"
fi
