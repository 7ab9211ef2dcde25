#!/usr/bin/env bash
# Gathers what scripts/gpu-bench.sh needs on a machine with a GPU driver but no compiler, no
# network and no Debian packages: the layertrace binary, every shared library it links except
# the C runtime and the GPU driver's own, the benchmark's scenes and the script itself.
#   scripts/gpu-bundle.sh BUILD_DIR OUT_DIR      (make gpu-bundle)
set -euo pipefail
build=${1:?usage: gpu-bundle.sh BUILD_DIR OUT_DIR}
out=${2:?usage: gpu-bundle.sh BUILD_DIR OUT_DIR}
root=$(cd "$(dirname "$0")/.." && pwd)
bin="$build/layertrace"
[ -x "$bin" ] || { echo "gpu-bundle: $bin not found (build it first: make build-cli)" >&2; exit 2; }
"$bin" --version | grep -q "GPU back end: built" || { echo "gpu-bundle: $bin has no GPU back end (see docs/gpu.md)" >&2; exit 2; }
for f in fzk-haus.json am-thornish.json; do
  grep -o '"\.\./data/models/[^"]*"' "$root/scenes/$f" | tr -d '"' | while read -r m; do
    [ -f "$root/scenes/$m" ] || { echo "gpu-bundle: scenes/$m missing (run make fetch)" >&2; exit 2; }
  done
done
rm -rf "$out.tmp"
mkdir -p "$out.tmp/lib" "$out.tmp/scenes" "$out.tmp/data/models" "$out.tmp/scripts"
cp "$bin" "$out.tmp/layertrace"
# The C runtime comes with every Linux; libEGL/libGL dispatch and the vendor drivers come with
# the GPU driver (libglvnd's loader is bundled: a bare machine may lack it, and it finds the
# driver's EGL vendor at run time).
ldd "$bin" | awk '/=> \// {print $3}' | while read -r lib; do
  case "$(basename "$lib")" in
    libc.so*|libm.so*|libpthread.so*|libdl.so*|librt.so*|ld-linux*|libgcc_s.so*) ;;
    libnvidia*|libEGL_nvidia*|libGLX_nvidia*|libEGL_mesa*|libGLX_mesa*|libgallium*) ;;
    *) cp -L "$lib" "$out.tmp/lib/" ;;
  esac
done
for l in libEGL.so.1 libGLdispatch.so.0 libOpenGL.so.0; do
  p=$(ldconfig -p | awk -v l="$l" '$1 == l {print $NF; exit}')
  [ -n "$p" ] && cp -L "$p" "$out.tmp/lib/"
done
cp -r "$root/scenes/default.json" "$root/scenes/default" "$root/scenes/fzk-haus.json" "$root/scenes/am-thornish.json" "$out.tmp/scenes/"
cp "$root/data/models/AC14-FZK-Haus.ifc" "$root/data/models/am_thornish.pk3" "$out.tmp/data/models/"
cp "$root/scripts/gpu-bench.sh" "$out.tmp/scripts/"
rm -rf "$out"
mv "$out.tmp" "$out"
echo "gpu-bundle: $out ($(du -sh "$out" | cut -f1)); on the GPU machine: $out/scripts/gpu-bench.sh"
