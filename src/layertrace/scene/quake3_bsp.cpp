// A Quake 3 BSP check before assimp reads one: assimp 5.2's Q3BSP importer trusts
// the lump directory and the face records, and a mutated map makes it read freed or foreign
// memory (found by fuzz_pk3). The file format (IBSP version 46: 17 lumps, each an offset and a
// length; faces index vertices, mesh vertices and textures) is public; these are exactly the
// lumps and fields the importer reads.
//
// And the curved surfaces the importer drops: Quake 3's patches (face type 2) are grids of
// biquadratic Bézier patches (the format's public descriptions; the engine tessellates them at
// load time), tessellated here into triangles.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <map>

#include <glm/geometric.hpp>

#include "layertrace/scene/load.h"
#include "layertrace/util/error.h"
#include "layertrace/util/memory.h"

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
/// A texture record's surface flag for surfaces the engine does not draw (q_shared.h SURF_NODRAW).
constexpr int32_t kSurfaceNoDraw = 0x80;

float f32(const unsigned char* p) {
  float v;
  std::memcpy(&v, p, 4);
  return v;
}

glm::vec3 vec3At(const unsigned char* p) { return {f32(p), f32(p + 4), f32(p + 8)}; }

/// The quadratic Bernstein weights at t (exactly 1, 0, 0 at t = 0 and 0, 0, 1 at t = 1, so a
/// patch's corners are its corner control points bit for bit).
std::array<float, 3> bernstein(float t) {
  const float s = 1.0f - t;
  return {s * s, 2.0f * s * t, t * t};
}

/// Segments per patch along one direction. A quadratic Bézier's second derivative is the
/// constant 2(P0 − 2P1 + P2), so with L equal parameter steps its chords stay within
/// |P0 − 2P1 + P2| / (4L²) of it: L is the least that keeps that within the tolerance (the
/// engine picks its level from a similar error bound; r_subdivisions, 4 units by default). At most
/// 64 (a patch 64² units deep at a tolerance of 1), so that a hostile map cannot ask for
/// unbounded grids (their memory is checked too).
int segmentsFor(float deviation, float tolerance) {
  const float l = std::ceil(std::sqrt(deviation / (4.0f * tolerance)));
  return l < 64.0f ? std::max(1, int(l)) : 64;  // (a NaN from non-finite control points: 64; finalize() refuses the map)
}

}  // namespace

glm::vec2 quake3TexCoord(glm::vec2 st) { return {st.x, 1.0f - st.y}; }

namespace {

/// The lump directory: each lump's records and their count.
struct Directory {
  int64_t count[kLumps];
  const unsigned char* lump[kLumps];
};

template <class Bad>
Directory readDirectory(const unsigned char* data, size_t size, const Bad& bad) {
  if (size < kHeader || std::memcmp(data, "IBSP", 4) != 0) bad("no IBSP header");
  if (i32(data + 4) != 46) bad("version ", i32(data + 4), " (Quake 3 maps are version 46)");
  Directory d;
  for (int l = 0; l < kLumps; ++l) {
    const int64_t offset = i32(data + 8 + 8 * l), length = i32(data + 12 + 8 * l);
    if (offset < 0 || length < 0 || uint64_t(offset + length) > size)
      bad("lump ", l, " (offset ", offset, ", length ", length, ") lies outside the file of ", size, " bytes");
    if (length % kRecord[l] != 0) bad("lump ", l, " length ", length, " is not a multiple of its ", kRecord[l], "-byte records");
    d.count[l] = length / kRecord[l];
    d.lump[l] = data + offset;
  }
  return d;
}

}  // namespace

void validateQuake3Bsp(const unsigned char* data, size_t size, const std::string& name) {
  auto bad = [&](const auto&... why) { inputError("scene ", name, ": malformed Quake 3 map: ", why...); };
  const Directory d = readDirectory(data, size, bad);
  const int64_t* count = d.count;
  const unsigned char* const* lump = d.lump;
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

Quake3Patches tessellateQuake3Patches(const unsigned char* data, size_t size, float tolerance) {
  validateQuake3Bsp(data, size, "map");  // every index below is checked
  const Directory d = readDirectory(data, size, [](const auto&...) {});
  Quake3Patches out;
  for (int64_t t = 0; t < d.count[Textures]; ++t) {
    const char* name = reinterpret_cast<const char*>(d.lump[Textures] + t * kRecord[Textures]);
    out.shaders.emplace_back(name, std::find(name, name + 64, '\0'));
  }
  out.lightmaps.assign(d.lump[Lightmaps], d.lump[Lightmaps] + d.count[Lightmaps] * kRecord[Lightmaps]);
  std::map<std::string, uint32_t> keyIndex;
  uint64_t bytes = 0;
  for (int64_t f = 0; f < d.count[Faces]; ++f) {
    const unsigned char* r = d.lump[Faces] + f * kRecord[Faces];
    const int32_t texture = i32(r), type = i32(r + 8), vertex = i32(r + 12), lightmap = i32(r + 28), width = i32(r + 96),
                  height = i32(r + 100);
    // A grid that is not made of whole 3 × 3 patches is not a Bézier surface, and a patch whose
    // texture says "nodraw" (surface flag 0x80) is there for collisions only: the engine draws
    // neither. (q3map2's -patchmeta keeps every patch for collisions that way and writes its
    // drawn copy as triangles, which assimp reads: all 520 patches of am_thornish are nodraw.)
    if (type != 2 || width < 3 || height < 3 || width % 2 == 0 || height % 2 == 0) continue;
    if (i32(d.lump[Textures] + int64_t(texture) * kRecord[Textures] + 64) & kSurfaceNoDraw) continue;
    const auto point = [&](int row, int col) {
      return d.lump[Vertices] + (int64_t(vertex) + int64_t(row) * width + col) * kRecord[Vertices];
    };
    float du = 0.0f, dv = 0.0f;
    for (int row = 0; row < height; ++row)
      for (int c = 0; c + 2 < width; c += 2)
        du = std::max(du, glm::length(vec3At(point(row, c)) - 2.0f * vec3At(point(row, c + 1)) + vec3At(point(row, c + 2))));
    for (int col = 0; col < width; ++col)
      for (int c = 0; c + 2 < height; c += 2)
        dv = std::max(dv, glm::length(vec3At(point(c, col)) - 2.0f * vec3At(point(c + 1, col)) + vec3At(point(c + 2, col))));
    // One count per direction for the whole grid: neighbouring patches meet at the same vertices.
    const int lu = segmentsFor(du, tolerance), lv = segmentsFor(dv, tolerance);
    const int nu = (width - 1) / 2, nv = (height - 1) / 2, cols = nu * lu + 1, rows = nv * lv + 1;
    bytes += uint64_t(cols) * uint64_t(rows) * 24 + uint64_t(cols - 1) * uint64_t(rows - 1) * 2 * 16;
    checkAllocation("Quake 3 patches", bytes);
    const std::string key = cat(texture, ".", lightmap);
    const uint32_t k = keyIndex.emplace(key, uint32_t(out.keys.size())).first->second;
    if (k == out.keys.size()) out.keys.push_back(key);
    const auto base = uint32_t(out.positions.size());
    for (int gr = 0; gr < rows; ++gr) {
      const int pv = std::min(gr / lv, nv - 1);
      const std::array<float, 3> wv = bernstein(float(gr - pv * lv) / float(lv));
      for (int gc = 0; gc < cols; ++gc) {
        const int pu = std::min(gc / lu, nu - 1);
        const std::array<float, 3> wu = bernstein(float(gc - pu * lu) / float(lu));
        glm::vec3 p(0.0f), n(0.0f);
        glm::vec2 st(0.0f), lm(0.0f);
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < 3; ++b) {
            const unsigned char* v = point(2 * pv + a, 2 * pu + b);
            const float w = wv[a] * wu[b];
            p += w * vec3At(v);  // the vertex record: position, texture st, lightmap st, normal, colour
            st += w * glm::vec2(f32(v + 12), f32(v + 16));
            lm += w * glm::vec2(f32(v + 20), f32(v + 24));
            n += w * vec3At(v + 28);
          }
        out.positions.push_back(p);
        out.normals.push_back(n);
        out.texcoords.push_back(quake3TexCoord(st));
        out.lightmapCoords.push_back(quake3TexCoord(lm));
      }
    }
    // Two triangles per cell, each wound counter-clockwise around its vertices' normals (the
    // grid's own order depends on how the map was built); a cell of a collapsed row (a cone's
    // apex) gives no triangle.
    const auto add = [&](uint32_t a, uint32_t b, uint32_t c) {
      const glm::vec3 g = glm::cross(out.positions[b] - out.positions[a], out.positions[c] - out.positions[a]);
      if (g == glm::vec3(0.0f)) return;
      const glm::vec3 n = out.normals[a] + out.normals[b] + out.normals[c];
      out.triangles.push_back(glm::dot(g, n) < 0.0f ? glm::uvec3(a, c, b) : glm::uvec3(a, b, c));
      out.triKey.push_back(k);
    };
    for (int gr = 0; gr + 1 < rows; ++gr)
      for (int gc = 0; gc + 1 < cols; ++gc) {
        const auto a = uint32_t(base + uint64_t(gr) * uint64_t(cols) + uint64_t(gc)), b = a + 1, c = a + uint32_t(cols), e = c + 1;
        add(a, b, e);
        add(a, e, c);
      }
  }
  return out;
}

}  // namespace lt
