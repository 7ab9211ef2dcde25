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
# A textured Collada model: the duck and its texture, which it names as ./duckCM.tga.
extract assimp-testmodels usr/share/assimp/models/Collada/duck.dae "$DATA/models/duck/duck.dae"
extract assimp-testmodels usr/share/assimp/models/Collada/duckCM.tga "$DATA/models/duck/duckCM.tga"

# OpenArena's game archives, where the maps below find their textures and shader scripts
# (scene/quake3_textures.h looks in a baseoa/ folder beside a map): OpenArena 0.8.1's data and
# textures and the 0.8.5 and 0.8.8 patches.
OA=usr/share/games/openarena/baseoa
extract openarena-data "$OA/pak0.pk3" "$DATA/models/baseoa/pak0.pk3"
extract openarena-081-textures "$OA/pak4-textures.pk3" "$DATA/models/baseoa/pak4-textures.pk3"
extract openarena-085-data "$OA/pak6-patch085.pk3" "$DATA/models/baseoa/pak6-patch085.pk3"
extract openarena-088-data "$OA/pak6-patch088.pk3" "$DATA/models/baseoa/pak6-patch088.pk3"

# OpenArena maps: assimp reads only the first maps/*.bsp of an archive, so each map is repacked
# into its own uncompressed .pk3. am_thornish is the hall of the README's tables; oa_shouse has
# drawn Bézier patches (arches, pipes), which the loader tessellates.
repack_map() {
  local map=$1 dest="$DATA/models/$1.pk3"
  [ -s "$dest" ] && return 0
  local tmp
  tmp=$(mktemp -d)
  unzip -q -o "$DATA/models/baseoa/pak6-patch088.pk3" "maps/$map.bsp" -d "$tmp"
  (cd "$tmp" && zip -q -0 map.pk3 "maps/$map.bsp")
  mv "$tmp/map.pk3" "$dest.tmp" && mv "$dest.tmp" "$dest"
  rm -rf "$tmp"
  echo "fetch-scenes: $dest"
}
repack_map am_thornish
repack_map oa_shouse
echo "fetch-scenes: all scenes present in $DATA/models"
