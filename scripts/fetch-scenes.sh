#!/usr/bin/env bash
# Fetches the real scenes of docs/data.md into data/ (git-ignored), idempotently.
# Debian data packages are downloaded with `apt-get download` and unpacked locally;
# nothing is installed system-wide. JSON scene files with cameras live in scenes/.
set -euo pipefail
cd "$(dirname "$0")/.."
DATA=data
DEBS=$DATA/debs
mkdir -p "$DEBS" "$DATA/models"

# extract PACKAGE PATH-IN-PACKAGE DEST
extract() {
  local pkg=$1 path=$2 dest=$3
  [ -s "$dest" ] && return 0
  local deb
  deb=$(ls "$DEBS"/"${pkg}"_*.deb 2>/dev/null | head -n 1 || true)
  if [ -z "$deb" ]; then
    (cd "$DEBS" && apt-get download "$pkg" >/dev/null 2>&1) || {
      echo "fetch-scenes: apt-get download $pkg failed; running apt-get update first" >&2
      if [ "$(id -u)" -eq 0 ]; then apt-get update -qq; else sudo apt-get update -qq; fi
      (cd "$DEBS" && apt-get download "$pkg" >/dev/null)
    }
    deb=$(ls "$DEBS"/"${pkg}"_*.deb | head -n 1)
  fi
  local tmp
  tmp=$(mktemp -d)
  dpkg-deb --fsys-tarfile "$deb" | tar -x -C "$tmp" "./$path"
  mkdir -p "$(dirname "$dest")"
  mv "$tmp/$path" "$dest.tmp" && mv "$dest.tmp" "$dest"
  rm -rf "$tmp"
  echo "fetch-scenes: $dest"
}

extract assimp-testmodels usr/share/assimp/models/IFC/AC14-FZK-Haus.ifc "$DATA/models/AC14-FZK-Haus.ifc"
extract assimp-testmodels usr/share/assimp/models/glTF2/2CylinderEngine-glTF-Binary/2CylinderEngine.glb "$DATA/models/2CylinderEngine.glb"
extract assimp-testmodels usr/share/assimp/models/Collada/teapots.DAE "$DATA/models/teapots.DAE"
# A malformed model on which assimp's importer aborts (tests the CLI's handling of that).
extract assimp-testmodels usr/share/assimp/models/invalid/OutOfMemory.off "$DATA/models/invalid/OutOfMemory.off"
extract glmark2-data usr/share/glmark2/models/bunny.obj "$DATA/models/bunny.obj"
extract embree-tools usr/share/doc/embree3/models/cornell_box.obj "$DATA/models/cornell_box.obj"
extract embree-tools usr/share/doc/embree3/models/cornell_box.mtl "$DATA/models/cornell_box.mtl"

# OpenArena maps: assimp reads only the first maps/*.bsp of an archive, so each map is repacked
# into its own uncompressed .pk3. am_thornish is the hall of the README's tables; oa_shouse has
# drawn Bézier patches (arches, pipes), which the loader tessellates.
repack_map() {
  local map=$1 dest="$DATA/models/$1.pk3"
  [ -s "$dest" ] && return 0
  extract openarena-088-data usr/share/games/openarena/baseoa/pak6-patch088.pk3 "$DATA/debs/pak6-patch088.pk3"
  local tmp
  tmp=$(mktemp -d)
  unzip -q -o "$DATA/debs/pak6-patch088.pk3" "maps/$map.bsp" -d "$tmp"
  (cd "$tmp" && zip -q -0 map.pk3 "maps/$map.bsp")
  mv "$tmp/map.pk3" "$dest.tmp" && mv "$dest.tmp" "$dest"
  rm -rf "$tmp"
  echo "fetch-scenes: $dest"
}
repack_map am_thornish
repack_map oa_shouse
echo "fetch-scenes: all scenes present in $DATA/models"
