// A Quake 3 BSP check before assimp reads one (issue 16): assimp 5.2's Q3BSP importer trusts
// the lump directory and the face records, and a mutated map makes it read freed or foreign
// memory (found by fuzz_pk3). The file format (IBSP version 46: 17 lumps, each an offset and a
// length; faces index vertices, mesh vertices and textures) is public; these are exactly the
// lumps and fields the importer reads.
#include <cstring>

#include "layertrace/scene/load.h"
#include "layertrace/util/error.h"

namespace lt {

namespace {

int32_t i32(const unsigned char* p) {
  uint32_t v;
  std::memcpy(&v, p, 4);  // little-endian file, little-endian host (x86-64)
  return int32_t(v);
}

enum Lump { Entities, Textures, Planes, Nodes, Leafs, LeafFaces, LeafBrushes, Models, Brushes, BrushSides, Vertices,
            MeshVerts, Effects, Faces, Lightmaps, LightVolumes, VisData, kLumps };
/// Bytes per record of each lump (1: free-form).
constexpr int kRecord[kLumps] = {1, 72, 16, 36, 48, 4, 4, 40, 12, 8, 44, 4, 72, 104, 128 * 128 * 3, 8, 1};
constexpr size_t kHeader = 8 + 8 * kLumps;

}  // namespace

void validateQuake3Bsp(const unsigned char* data, size_t size, const std::string& name) {
  auto bad = [&](const auto&... why) { inputError("scene ", name, ": malformed Quake 3 map: ", why...); };
  if (size < kHeader || std::memcmp(data, "IBSP", 4) != 0) bad("no IBSP header");
  if (i32(data + 4) != 46) bad("version ", i32(data + 4), " (Quake 3 maps are version 46)");
  int64_t count[kLumps];
  const unsigned char* lump[kLumps];
  for (int l = 0; l < kLumps; ++l) {
    const int64_t offset = i32(data + 8 + 8 * l), length = i32(data + 12 + 8 * l);
    if (offset < 0 || length < 0 || uint64_t(offset + length) > size)
      bad("lump ", l, " (offset ", offset, ", length ", length, ") lies outside the file of ", size, " bytes");
    if (length % kRecord[l] != 0) bad("lump ", l, " length ", length, " is not a multiple of its ", kRecord[l], "-byte records");
    count[l] = length / kRecord[l];
    lump[l] = data + offset;
  }
  for (int64_t f = 0; f < count[Faces]; ++f) {
    const unsigned char* r = lump[Faces] + f * kRecord[Faces];
    const int64_t texture = i32(r), type = i32(r + 8), vertex = i32(r + 12), vertices = i32(r + 16), meshVert = i32(r + 20),
                  meshVerts = i32(r + 24), lightmap = i32(r + 28), width = i32(r + 96), height = i32(r + 100);
    if (texture < 0 || texture >= count[Textures]) bad("face ", f, " uses texture ", texture, " of ", count[Textures]);
    if (type < 1 || type > 4) bad("face ", f, " has type ", type);
    if (vertex < 0 || vertices < 0 || vertex + vertices > count[Vertices])
      bad("face ", f, " uses vertices ", vertex, "+", vertices, " of ", count[Vertices]);
    if (meshVert < 0 || meshVerts < 0 || meshVert + meshVerts > count[MeshVerts])
      bad("face ", f, " uses mesh vertices ", meshVert, "+", meshVerts, " of ", count[MeshVerts]);
    // Negative lightmap numbers are the engine's special values (-1 none, -3 by vertex, ...).
    if (lightmap >= count[Lightmaps]) bad("face ", f, " uses lightmap ", lightmap, " of ", count[Lightmaps]);
    for (int64_t m = 0; m < meshVerts; ++m) {
      const int64_t v = i32(lump[MeshVerts] + 4 * (meshVert + m));
      if (v < 0 || v >= vertices) bad("face ", f, " mesh vertex ", m, " is ", v, ", beyond its ", vertices, " vertices");
    }
    if (type == 2 && (width < 2 || height < 2 || width * height > vertices))
      bad("face ", f, " is a ", width, "×", height, " patch over ", vertices, " vertices");
  }
}

}  // namespace lt
