#!/usr/bin/env bash
# Compiles layertrace's vector code for aarch64 with Debian's cross compiler
# (g++-aarch64-linux-gnu): every file that Google Highway compiles per target (NEON and the
# scalar emulation there) and the lane helpers' test. Objects only: linking and running them
# needs the arm64 builds of Embree, assimp, oneTBB and OpenEXR and an Arm machine or qemu-user
# (docs/install.md, "Arm").
#   scripts/cross-aarch64.sh          the vector code and its test (about a minute)
#   scripts/cross-aarch64.sh --all    every library source as well
set -euo pipefail
cd "$(dirname "$0")/.."
CXX=${CXX_AARCH64:-aarch64-linux-gnu-g++}
if ! command -v "$CXX" >/dev/null; then
  echo "cross-aarch64: $CXX not found (apt-get install g++-aarch64-linux-gnu)" >&2
  exit 2
fi
out=$(mktemp -d /tmp/layertrace-aarch64.XXXXXX)
trap 'rm -rf "$out"' EXIT
mkdir -p "$out/generated/layertrace"
# (the headers the build generates: the commit the version text names, the API's export macro)
echo '#define LAYERTRACE_COMMIT "cross"' > "$out/generated/layertrace/commit.h"
mkdir -p "$out/generated/layertrace/api"
echo '#define LAYERTRACE_API' > "$out/generated/layertrace/api/export.h"
# The project's own flags (CMakeLists.txt): no FMA contraction, the same Highway targets policy.
# Host headers come after the cross compiler's own (-idirafter): the header-only libraries (GLM,
# Highway, nlohmann-json, GoogleTest) are the same on every architecture.
flags=(-std=c++20 -O2 -ffp-contract=off -Wall -Wextra -Wpedantic -Wshadow -Wno-missing-field-initializers -Werror
       -DHWY_COMPILE_ALL_ATTAINABLE "-DHWY_DISABLED_TARGETS=(HWY_SSSE3|HWY_SVE|HWY_SVE2|HWY_SVE_256|HWY_SVE2_128)"
       -DGLM_FORCE_XYZW_ONLY -DGLM_ENABLE_EXPERIMENTAL -DLAYERTRACE_COUNTERS=1 -DLAYERTRACE_VERSION=\"cross\"
       -DLAYERTRACE_BUILD_TYPE=\"cross\" -DLAYERTRACE_TOOLS_DIR=\"tools\" -DLAYERTRACE_SOURCE_DIR=\"$PWD\"
       -Wno-psabi -Isrc -Itests -I"$out/generated" -idirafter /usr/include -idirafter /usr/include/OpenEXR -idirafter /usr/include/Imath -idirafter /usr/include/stb)
mapfile -t files < <(grep -l 'hwy/foreach_target.h' -r src/layertrace --include='*.cpp' | sort)
files+=(tests/lanes_test.cpp)
if [ "${1:-}" = "--all" ]; then
  mapfile -t all < <(find src/layertrace -name '*.cpp' ! -name '*_test.cpp' ! -path '*/gpu/*' | sort)
  files=("${all[@]}" tests/lanes_test.cpp)
fi
echo "cross-aarch64: compiling ${#files[@]} files with $($CXX -dumpversion) for aarch64"
printf '%s\n' "${files[@]}" | xargs -P "$(nproc)" -I{} sh -c '"$0" "$@" -c {} -o "'"$out"'/$(echo {} | tr / _).o"' "$CXX" "${flags[@]}"
# Every per-target file must hold the NEON copy.
for f in $(grep -l 'hwy/foreach_target.h' -r src/layertrace --include='*.cpp'); do
  o="$out/$(echo "$f" | tr / _).o"
  symbols=$(aarch64-linux-gnu-nm -C "$o")
  grep -q 'N_NEON' <<<"$symbols" || { echo "cross-aarch64: $f has no NEON code" >&2; exit 1; }
done
echo "cross-aarch64: ok (NEON and scalar copies of every vector loop)"
