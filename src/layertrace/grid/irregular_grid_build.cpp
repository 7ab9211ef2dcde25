#include <algorithm>
#include <cstddef>
#include <limits>
#include <atomic>
#include <chrono>
#include <cmath>

#include <glm/geometric.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "layertrace/util/parallel.h"
#include "layertrace/grid/irregular_grid.h"
#include "layertrace/util/error.h"
#include "layertrace/util/memory.h"

namespace lt {

bool triangleBoxOverlap(glm::vec3 a, glm::vec3 b, glm::vec3 c, glm::vec3 boxLo, glm::vec3 boxHi, float eps) {
  // The box widened by eps and by the rounding of its centre and of the vertices' offsets from
  // it: a few ulps of the coordinates' magnitude. Without the latter a thin box far from the
  // origin (a flat scene's slab, 4e-4 wide at x = -1.146) rejected a triangle lying exactly on
  // the boundary of two such boxes from both sides, and the grid missed it.
  const glm::vec3 magnitude = glm::max(glm::abs(boxLo), glm::abs(boxHi));
  const glm::vec3 center = (boxLo + boxHi) * 0.5f,
                  half = (boxHi - boxLo) * 0.5f + glm::vec3(eps) + magnitude * (4.0f * std::numeric_limits<float>::epsilon());
  const glm::vec3 v[3] = {a - center, b - center, c - center};
  for (int i = 0; i < 3; ++i) {  // box normals
    const float mn = std::min({v[0][i], v[1][i], v[2][i]}), mx = std::max({v[0][i], v[1][i], v[2][i]});
    if (mn > half[i] || mx < -half[i]) return false;
  }
  const glm::vec3 e[3] = {v[1] - v[0], v[2] - v[1], v[0] - v[2]};
  const glm::vec3 n = glm::cross(e[0], e[1]);  // triangle normal
  {
    const float r = half.x * std::abs(n.x) + half.y * std::abs(n.y) + half.z * std::abs(n.z);
    const float s = glm::dot(n, v[0]);
    if (std::abs(s) > r * (1.0f + 1e-5f) + 1e-30f) return false;
  }
  for (int i = 0; i < 3; ++i)  // edge × box axis
    for (int k = 0; k < 3; ++k) {
      glm::vec3 axis(0.0f);
      axis[k] = 1.0f;
      const glm::vec3 ax = glm::cross(e[i], axis);
      if (glm::dot(ax, ax) < 1e-30f) continue;
      const float p0 = glm::dot(v[0], ax), p1 = glm::dot(v[1], ax), p2 = glm::dot(v[2], ax);
      const float r = half.x * std::abs(ax.x) + half.y * std::abs(ax.y) + half.z * std::abs(ax.z);
      if (std::min({p0, p1, p2}) > r * (1.0f + 1e-5f) || std::max({p0, p1, p2}) < -r * (1.0f + 1e-5f)) return false;
    }
  return true;
}

GridTopLevel gridTopLevel(const Scene& scene, const GridConfig& cfg) {
  GridTopLevel out;
  const Bounds b = scene.bounds();
  const glm::vec3 ext = b.hi - b.lo;
  // Padding relative to the extent and to the coordinates' magnitude: a flat scene (one axis
  // of zero extent) or a tiny one far from the origin still gets a box of positive volume
  // whose sides survive float rounding (1e-6 alone vanishes next to 1e6).
  const float magnitude = std::max({1.0f, glm::length(b.lo), glm::length(b.hi)});
  const float pad = std::max(1e-4f * glm::length(ext), 1e-5f * magnitude);
  out.lo = b.lo - glm::vec3(pad);
  out.hi = b.hi + glm::vec3(pad);
  const glm::vec3 d = out.hi - out.lo;
  const float volume = d.x * d.y * d.z;
  const float density = std::cbrt(cfg.lambda1 * float(scene.triangleCount()) / volume);  // Cleary et al.
  for (int i = 0; i < 3; ++i) out.top[i] = std::clamp(int(d[i] * density), 1, 512);
  return out;
}

std::array<uint8_t, 3> topCellDepth(const GridConfig& cfg, glm::vec3 topSize, size_t refs) {
  std::array<uint8_t, 3> depth{0, 0, 0};
  if (refs == 0) return depth;
  const float topVolume = topSize.x * topSize.y * topSize.z;
  const float dens = std::cbrt(cfg.lambda2 * float(refs) / topVolume);
  uint8_t deepest = 0;
  for (int i = 0; i < 3; ++i) {
    depth[size_t(i)] = uint8_t(std::clamp(int(std::ceil(std::log2(std::max(topSize[i] * dens, 1.0f)))), 0, cfg.maxDepth));
    deepest = std::max(deepest, depth[size_t(i)]);
  }
  if (cfg.oneDepthPerCell) depth = {deepest, deepest, deepest};
  return depth;
}

/// Everything the build needs beside the grid itself.
struct GridBuilder {
  IrregularGrid& g;
  const Scene& scene;
  const GridConfig& cfg;
  std::vector<std::vector<uint32_t>> cellRefs;  ///< during the build: sorted references per cell
  std::vector<uint32_t> forward;                ///< merged cells point to the cell that absorbed them
  /// During merging: the live cells in increasing id (a pass visits these, not every cell ever
  /// made — on a flat scene most initial cells are merged away early, and revisiting them and
  /// clearing per-cell arrays each pass made the build quadratic-looking: 45 s on 240 k triangles).
  std::vector<uint32_t> liveCells;
  std::vector<uint8_t> touched;  ///< per cell id: merged in the current pass (all 0 between passes)

  glm::vec3 voxelLo(const int v[3]) const { return g.lo_ + glm::vec3(v[0], v[1], v[2]) * g.voxel_; }
  float area(const int lo[3], const int hi[3]) const {
    const glm::vec3 e = glm::vec3(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]) * g.voxel_;
    return e.x * e.y + e.y * e.z + e.z * e.x;
  }
  uint32_t live(uint32_t c) const {
    while (forward[c] != c) c = forward[c];
    return c;
  }

  void initialGrid() {
    const GridTopLevel level = gridTopLevel(scene, cfg);
    g.lo_ = level.lo, g.hi_ = level.hi;
    const glm::vec3 d = g.hi_ - g.lo_;
    for (int i = 0; i < 3; ++i) g.top_[i] = level.top[i];
    const glm::vec3 topSize = level.topSize();
    const size_t numTop = size_t(g.top_[0]) * size_t(g.top_[1]) * size_t(g.top_[2]);
    // Per top cell: its reference list, depth, leaf offset and traversal entry.
    checkAllocation(cat("the irregular grid's top level (", numTop, " cells)"),
                    uint64_t(numTop) * (sizeof(std::vector<uint32_t>) + sizeof(uint8_t) + sizeof(uint32_t) + 2 * sizeof(uint32_t)));

    // References of the top cells (exact triangle/box overlap): pairs per chunk of triangles in
    // parallel, then gathered in chunk order, so each cell's list stays sorted by triangle.
    const size_t numTris = scene.triangleCount(), chunk = 4096;
    std::vector<std::vector<std::pair<uint32_t, uint32_t>>> pairs((numTris + chunk - 1) / chunk);
    parallelFor(size_t(0), pairs.size(), [&](size_t k) {
      for (uint32_t t = uint32_t(k * chunk); t < std::min(numTris, (k + 1) * chunk); ++t) {
        const glm::vec3 a = scene.positions[scene.triangles[t].x], bb = scene.positions[scene.triangles[t].y],
                        c = scene.positions[scene.triangles[t].z];
        const glm::vec3 mn = glm::min(a, glm::min(bb, c)), mx = glm::max(a, glm::max(bb, c));
        int lo[3], hi[3];
        for (int i = 0; i < 3; ++i) {
          lo[i] = std::clamp(int((mn[i] - g.lo_[i]) / topSize[i]), 0, g.top_[i] - 1);
          hi[i] = std::clamp(int((mx[i] - g.lo_[i]) / topSize[i]), 0, g.top_[i] - 1);
        }
        for (int z = lo[2]; z <= hi[2]; ++z)
          for (int y = lo[1]; y <= hi[1]; ++y)
            for (int x = lo[0]; x <= hi[0]; ++x) {
              const glm::vec3 bl = g.lo_ + glm::vec3(x, y, z) * topSize;
              if (triangleBoxOverlap(a, bb, c, bl, bl + topSize, 1e-5f * glm::length(topSize)))
                pairs[k].emplace_back(uint32_t((size_t(z) * size_t(g.top_[1]) + size_t(y)) * size_t(g.top_[0]) + size_t(x)), t);
            }
      }
    });
    std::vector<std::vector<uint32_t>> topRefs(numTop);
    for (const auto& list : pairs)
      for (const auto& [cell, t] : list) topRefs[cell].push_back(t);
    pairs.clear();
    // Octree depth per top cell: the same formula with λ2 and the cell's own count and volume,
    // per axis (irregular_grid.h), or the longest axis's for all three (oneDepthPerCell: the
    // paper's D = ⌈log2 max(R_x, R_y, R_z)⌉, which is the largest of the per-axis depths).
    g.topDepth_.assign(numTop, {0, 0, 0});
    g.depth_ = 0;
    for (size_t c = 0; c < numTop; ++c) {
      g.topDepth_[c] = topCellDepth(cfg, topSize, topRefs[c].size());
      g.depth_ = std::max({g.depth_, int(g.topDepth_[c][0]), int(g.topDepth_[c][1]), int(g.topDepth_[c][2])});
    }
    for (int i = 0; i < 3; ++i) g.virt_[i] = g.top_[i] << g.depth_;
    g.voxel_ = d / glm::vec3(g.virt_[0], g.virt_[1], g.virt_[2]);

    // Leaves: each top cell fully subdivided to its depth; leaf references from its top cell's.
    g.topOffset_.resize(numTop + 1);
    uint64_t leaves = 0;
    auto leafBits = [&](size_t c) { return g.topDepth_[c][0] + g.topDepth_[c][1] + g.topDepth_[c][2]; };
    for (size_t c = 0; c < numTop; ++c) leaves += uint64_t(1) << leafBits(c);
    if (leaves > 0xFFFFFFFFull) inputError("irregular grid: ", leaves, " cells exceed the 32-bit cell index (use lower --lambda1/--lambda2)");
    checkAllocation(cat("the irregular grid (", leaves, " cells)"), leaves * (sizeof(GridCell) + sizeof(uint32_t) + sizeof(std::vector<uint32_t>) + 8));
    uint32_t total = 0;
    for (size_t c = 0; c < numTop; ++c) g.topOffset_[c] = total, total += 1u << leafBits(c);
    g.topOffset_[numTop] = total;
    g.leaf_.resize(total);
    g.cells_.resize(total);
    cellRefs.resize(total);
    parallelFor(size_t(0), numTop, [&](size_t c) {
      const int tx = int(c % size_t(g.top_[0])), ty = int(c / size_t(g.top_[0]) % size_t(g.top_[1])),
                tz = int(c / (size_t(g.top_[0]) * size_t(g.top_[1])));
      int n[3], span[3];
      for (int i = 0; i < 3; ++i) n[i] = 1 << g.topDepth_[c][size_t(i)], span[i] = 1 << (g.depth_ - g.topDepth_[c][size_t(i)]);
      const int base[3] = {tx << g.depth_, ty << g.depth_, tz << g.depth_};
      auto leafId = [&](int x, int y, int z) { return g.topOffset_[c] + uint32_t((z * n[1] + y) * n[0] + x); };
      for (int z = 0; z < n[2]; ++z)
        for (int y = 0; y < n[1]; ++y)
          for (int x = 0; x < n[0]; ++x) {
            const uint32_t id = leafId(x, y, z);
            g.leaf_[id] = id;
            GridCell& cell = g.cells_[id];
            const int off[3] = {x, y, z};
            for (int i = 0; i < 3; ++i) {
              cell.lo[i] = cell.elo[i] = base[i] + off[i] * span[i];
              cell.hi[i] = cell.ehi[i] = cell.lo[i] + span[i];
            }
          }
      if (leafBits(c) == 0) {
        cellRefs[g.topOffset_[c]] = topRefs[c];
        return;
      }
      // Each triangle is tested only against the leaves its bounding box overlaps.
      const glm::vec3 leafSize = g.voxel_ * glm::vec3(span[0], span[1], span[2]);
      const glm::vec3 cellLo = g.lo_ + glm::vec3(base[0], base[1], base[2]) * g.voxel_;
      for (uint32_t t : topRefs[c]) {
        const glm::uvec3 tri = scene.triangles[t];
        const glm::vec3 a = scene.positions[tri.x], bb = scene.positions[tri.y], cc = scene.positions[tri.z];
        const glm::vec3 mn = (glm::min(a, glm::min(bb, cc)) - cellLo) / leafSize, mx = (glm::max(a, glm::max(bb, cc)) - cellLo) / leafSize;
        int lo[3], hi[3];
        for (int i = 0; i < 3; ++i) {
          lo[i] = std::clamp(int(std::floor(mn[i])) - 1, 0, n[i] - 1);
          hi[i] = std::clamp(int(std::floor(mx[i])) + 1, 0, n[i] - 1);
        }
        for (int z = lo[2]; z <= hi[2]; ++z)
          for (int y = lo[1]; y <= hi[1]; ++y)
            for (int x = lo[0]; x <= hi[0]; ++x) {
              const uint32_t id = leafId(x, y, z);
              const GridCell& cell = g.cells_[id];
              const glm::vec3 bl = voxelLo(cell.lo), bh = voxelLo(cell.hi);
              if (triangleBoxOverlap(a, bb, cc, bl, bh, 1e-5f * glm::length(bh - bl))) cellRefs[id].push_back(t);
            }
      }
    });
    forward.resize(total);
    for (uint32_t i = 0; i < total; ++i) forward[i] = i;
    g.stats_.cellsInitial = total;
    for (int i = 0; i < 3; ++i) g.stats_.top[i] = g.top_[i];
    g.stats_.depth = g.depth_;
  }

  /// Current (live) cell containing virtual voxel v.
  uint32_t at(const int v[3]) const { return live(g.buildCellAt(v)); }

  static bool subset(const std::vector<uint32_t>& small, const std::vector<uint32_t>& big) {
    return std::includes(big.begin(), big.end(), small.begin(), small.end());
  }

  /// The cell a merge along `axis` would join to live cell a — its neighbour beyond A's upper
  /// face, if that neighbour has exactly A's extent across the axis and the SAH criterion
  /// accepts the union — or 0xFFFFFFFF when there is no such merge.
  uint32_t mergeCandidate(uint32_t a, int axis) const {
    constexpr uint32_t none = 0xFFFFFFFFu;
    const int u = (axis + 1) % 3, w = (axis + 2) % 3;
    const GridCell& A = g.cells_[a];
    if (A.hi[axis] >= g.virt_[axis]) return none;
    int probe[3];
    probe[axis] = A.hi[axis], probe[u] = A.lo[u], probe[w] = A.lo[w];
    const uint32_t b = at(probe);
    if (b == a) return none;
    const GridCell& B = g.cells_[b];
    if (B.lo[axis] != A.hi[axis] || B.lo[u] != A.lo[u] || B.hi[u] != A.hi[u] || B.lo[w] != A.lo[w] || B.hi[w] != A.hi[w]) return none;
    // |R(A) ∪ R(B)| of the two sorted lists, without building the union.
    const std::vector<uint32_t>& ra = cellRefs[a];
    const std::vector<uint32_t>& rb = cellRefs[b];
    size_t i = 0, j = 0, n = 0;
    while (i < ra.size() && j < rb.size()) {
      const uint32_t x = ra[i], y = rb[j];
      i += x <= y, j += y <= x, ++n;
    }
    n += (ra.size() - i) + (rb.size() - j);
    int lo[3] = {A.lo[0], A.lo[1], A.lo[2]}, hi[3] = {A.hi[0], A.hi[1], A.hi[2]};
    hi[axis] = B.hi[axis];
    const float ct = cfg.traversalCost;
    const float before = area(A.lo, A.hi) * (ct + float(ra.size())) + area(B.lo, B.hi) * (ct + float(rb.size()));
    const float after = area(lo, hi) * (ct + float(n));
    return after > before ? none : b;
  }

  /// Joins live cell b into a along `axis`.
  void join(uint32_t a, uint32_t b, int axis) {
    GridCell& A = g.cells_[a];
    A.hi[axis] = A.ehi[axis] = g.cells_[b].hi[axis];
    std::vector<uint32_t> uni;
    uni.reserve(cellRefs[a].size() + cellRefs[b].size());
    std::set_union(cellRefs[a].begin(), cellRefs[a].end(), cellRefs[b].begin(), cellRefs[b].end(), std::back_inserter(uni));
    cellRefs[a].swap(uni);
    std::vector<uint32_t>().swap(cellRefs[b]);
    forward[b] = a;
  }

  /// Cell merging (Pérard-Gayot et al. 2017): one pass along `axis`; returns the number of merges.
  /// A greedy pass in cell order: a cell not yet merged in this pass joins its candidate neighbour
  /// when that one has not been merged in this pass either.
  ///
  /// Parallel, and the same cells as that serial pass: a cell's candidate and the
  /// SAH decision depend only on the two cells' state before the pass — a cell's box and
  /// references change only when it is merged, and a merged cell is out for the rest of the
  /// pass — so the candidates are found in parallel, the greedy choice runs serially over them
  /// (a byte per cell), and the chosen pairs, disjoint, are joined in parallel. The serial pass
  /// (GridConfig::parallelMerge = false) stays as the reference the tests compare with.
  size_t mergePass(int axis) {
    constexpr uint32_t none = 0xFFFFFFFFu;
    std::vector<std::pair<uint32_t, uint32_t>> pairs;
    if (!cfg.parallelMerge) {
      for (const uint32_t a : liveCells) {
        if (touched[a]) continue;
        const uint32_t b = mergeCandidate(a, axis);
        if (b == none || touched[b]) continue;
        join(a, b, axis);
        touched[a] = touched[b] = 1;
        pairs.emplace_back(a, b);
      }
    } else {
      const size_t n = liveCells.size();
      std::vector<uint32_t> candidate(n, none);
      parallelFor(tbb::blocked_range<size_t>(0, n, 512), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t k = r.begin(); k != r.end(); ++k) candidate[k] = mergeCandidate(liveCells[k], axis);
      });
      for (size_t k = 0; k < n; ++k) {
        const uint32_t a = liveCells[k], b = candidate[k];
        if (b == none || touched[a] || touched[b]) continue;
        touched[a] = touched[b] = 1;
        pairs.emplace_back(a, b);
      }
      parallelFor(size_t(0), pairs.size(), [&](size_t k) { join(pairs[k].first, pairs[k].second, axis); });
    }
    for (const auto& [a, b] : pairs) touched[a] = touched[b] = 0;
    std::erase_if(liveCells, [&](uint32_t c) { return forward[c] != c; });
    return pairs.size();
  }

  void merge() {
    liveCells.clear();
    for (uint32_t c = 0; c < uint32_t(g.cells_.size()); ++c)
      if (forward[c] == c) liveCells.push_back(c);
    touched.assign(g.cells_.size(), 0);
    size_t count = liveCells.size();
    for (int round = 0; round < 64; ++round) {
      size_t merged = 0;
      for (int axis = 0; axis < 3; ++axis) merged += mergePass(axis), ++g.stats_.mergePasses;
      const size_t after = count - merged;
      const bool done = float(after) >= cfg.alpha * float(count);
      count = after;
      if (done) break;
    }
    std::vector<uint32_t>().swap(liveCells);
    std::vector<uint8_t>().swap(touched);
  }

  /// Compacts live cells, rewrites the voxel map, flattens the references.
  void compact() {
    std::vector<uint32_t> newId(g.cells_.size(), 0xFFFFFFFFu);
    std::vector<GridCell> cells;
    for (uint32_t c = 0; c < g.cells_.size(); ++c)
      if (forward[c] == c) newId[c] = uint32_t(cells.size()), cells.push_back(g.cells_[c]);
    for (uint32_t& l : g.leaf_) l = newId[live(l)];
    std::vector<std::vector<uint32_t>> refs(cells.size());
    for (uint32_t c = 0; c < g.cells_.size(); ++c)
      if (forward[c] == c) refs[newId[c]].swap(cellRefs[c]);
    cellRefs.swap(refs);
    g.cells_.swap(cells);
    forward.resize(g.cells_.size());
    for (uint32_t i = 0; i < forward.size(); ++i) forward[i] = i;
  }

  /// Cell expansion (Pérard-Gayot et al. 2017): grow each exit face over the neighbours beyond it
  /// when all of them reference a subset of this cell's primitives (R(B) ⊆ R(A)); binary per face,
  /// by the thinnest neighbour's depth.
  size_t expandPass() {
    // Each cell only changes its own expanded box and reads its neighbours' cells and
    // references, which expansion never changes: the cells expand in parallel, and the result
    // does not depend on the order.
    std::atomic<size_t> grown{0};
    parallelFor(tbb::blocked_range<uint32_t>(0, uint32_t(g.cells_.size()), 256), [&](const tbb::blocked_range<uint32_t>& r) {
      std::vector<uint32_t> neighbours;
      size_t local = 0;
      for (uint32_t a = r.begin(); a != r.end(); ++a)
        for (int axis = 0; axis < 3; ++axis)
          for (int side = 0; side < 2; ++side) local += expandFace(a, axis, side, neighbours);
      grown += local;
    });
    return grown;
  }

  /// Tries to move one exit face of cell a over the voxel layers beyond it.
  bool expandFace(uint32_t a, int axis, int side, std::vector<uint32_t>& neighbours) {
    GridCell& A = g.cells_[a];
    const int u = (axis + 1) % 3, w = (axis + 2) % 3;
    const int face = side ? A.ehi[axis] : A.elo[axis];
    if ((side && face >= g.virt_[axis]) || (!side && face <= 0)) return false;
    const int layer = side ? face : face - 1;  // voxel layer just beyond the face
    int depth = 1 << 30;
    neighbours.clear();
    for (int vw = A.elo[w]; vw < A.ehi[w];) {
      int nextW = A.ehi[w];
      for (int vu = A.elo[u]; vu < A.ehi[u];) {
        int p[3];
        p[axis] = layer, p[u] = vu, p[w] = vw;
        const uint32_t b = g.buildCellAt(p);
        const GridCell& B = g.cells_[b];
        if (b != a) neighbours.push_back(b);
        depth = std::min(depth, side ? B.hi[axis] - face : face - B.lo[axis]);
        nextW = std::min(nextW, B.hi[w]);
        vu = B.hi[u];
      }
      vw = nextW;
    }
    if (depth <= 0 || depth == (1 << 30)) return false;
    // The slab the face would sweep.
    int slo[3] = {A.elo[0], A.elo[1], A.elo[2]}, shi[3] = {A.ehi[0], A.ehi[1], A.ehi[2]};
    slo[axis] = side ? face : face - depth;
    shi[axis] = side ? face + depth : face;
    for (uint32_t b : neighbours) {
      if (subset(cellRefs[b], cellRefs[a])) continue;
      if (!cfg.partialExpansion) return false;
      // Partial expansion: only B's primitives inside the swept part of B must be in R(A).
      int blo[3], bhi[3];
      for (int i = 0; i < 3; ++i) blo[i] = std::max(slo[i], g.cells_[b].lo[i]), bhi[i] = std::min(shi[i], g.cells_[b].hi[i]);
      const glm::vec3 lo = voxelLo(blo), hi = voxelLo(bhi);
      const float eps = 1e-5f * glm::length(hi - lo);
      for (uint32_t t : cellRefs[b]) {
        if (std::binary_search(cellRefs[a].begin(), cellRefs[a].end(), t)) continue;
        const glm::uvec3 tri = scene.triangles[t];
        if (triangleBoxOverlap(scene.positions[tri.x], scene.positions[tri.y], scene.positions[tri.z], lo, hi, eps)) return false;
      }
    }
    if (side) A.ehi[axis] += depth;
    else A.elo[axis] -= depth;
    return true;
  }
};

IrregularGrid::IrregularGrid(const Scene& scene, const GridConfig& config) : scene_(&scene), cutOuts_(scene.anyCutOut()) {
  if (!(config.lambda1 > 0.0f)) inputError("--lambda1 ", config.lambda1, ": must be positive");
  if (!(config.lambda2 > 0.0f)) inputError("--lambda2 ", config.lambda2, ": must be positive");
  if (config.maxDepth < 0 || config.maxDepth > 15) inputError("--grid-max-depth ", config.maxDepth, ": must be between 0 and 15");
  const auto start = std::chrono::steady_clock::now();
  auto since = [](std::chrono::steady_clock::time_point t) {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
  };
  GridBuilder b{*this, scene, config, {}, {}};
  b.initialGrid();
  // The voxel map's top level is final now (merging relabels leaves only): the builder's
  // lookups use buildCellAt too.
  topCells_.resize(topDepth_.size());
  for (size_t c = 0; c < topDepth_.size(); ++c) {
    const std::array<uint8_t, 3> d = topDepth_[c];
    topCells_[c] = {topOffset_[c], {uint8_t(depth_ - d[0]), uint8_t(depth_ - d[1]), uint8_t(depth_ - d[2])}, d[0], uint8_t(d[0] + d[1])};
  }
  stats_.initialMs = since(start);
  auto t = std::chrono::steady_clock::now();
  if (config.merge) b.merge();
  b.compact();
  stats_.mergeMs = since(t);
  stats_.cellsAfterMerge = cells_.size();
  t = std::chrono::steady_clock::now();
  for (int p = 0; p < config.expansionPasses; ++p) stats_.expandedFaces += b.expandPass();
  stats_.expandMs = since(t);
  uint64_t refCount = 0;
  for (size_t c = 0; c < cells_.size(); ++c) refCount += b.cellRefs[c].size();
  if (refCount > 0xFFFFFFFFull) inputError("irregular grid: ", refCount, " references exceed the 32-bit reference index");
  checkAllocation(cat("the irregular grid's references (", refCount, ")"), refCount * sizeof(uint32_t));
  refs_.reserve(refCount);
  for (size_t c = 0; c < cells_.size(); ++c) {
    cells_[c].refBegin = uint32_t(refs_.size());
    refs_.insert(refs_.end(), b.cellRefs[c].begin(), b.cellRefs[c].end());
    cells_[c].refEnd = uint32_t(refs_.size());
  }
  stats_.refs = refs_.size();
  packForTraversal();
  stats_.buildMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

IrregularGrid::Packed IrregularGrid::packed() const {
  static_assert(sizeof(TopCell) == 12 && offsetof(TopCell, shift) == 4 && offsetof(TopCell, bits1) == 7 && offsetof(TopCell, bits2) == 8,
                "the layout Packed documents");
  static_assert(sizeof(TriangleBlock) == 160);
  return {{reinterpret_cast<const unsigned char*>(topCells_.data()), topCells_.size() * sizeof(TopCell)},
          {walkLeaf_.data(), walkLeaf_.size()},
          {reinterpret_cast<const unsigned char*>(walk_.data()), walk_.size() * sizeof(Line)}};
}

void IrregularGrid::packForTraversal() {
  invVoxel_ = 1.0f / voxel_;
  // Lay the cells out: record, blocks, padding to the next 64-byte line.
  std::vector<uint64_t> unitOf(cells_.size());
  uint64_t units = 0;
  static_assert(kLanes == 4 && sizeof(TriangleBlock) / kUnit == 5, "cellUnits' layout");
  for (size_t c = 0; c < cells_.size(); ++c) {
    unitOf[c] = units;
    units += cellUnits(cells_[c].refEnd - cells_[c].refBegin);  // (each cell starts on an even unit)
  }
  if (units > 0xFFFFFFFFull) inputError("irregular grid: ", units * kUnit, " bytes of cells and triangle blocks exceed the 32-bit cell index");
  checkAllocation(cat("the irregular grid's triangle blocks (", units * kUnit, " bytes)"), units * kUnit + leaf_.size() * sizeof(uint32_t));
  walk_.resize(units / 2);
  walkLeaf_.resize(leaf_.size());
  for (size_t l = 0; l < leaf_.size(); ++l) walkLeaf_[l] = uint32_t(unitOf[leaf_[l]]);
  auto* base = reinterpret_cast<unsigned char*>(walk_.data());
  parallelFor(0, int(cells_.size()), [&](int c) {
    const GridCell& g = cells_[size_t(c)];
    const uint32_t n = g.refEnd - g.refBegin;
    auto* cell = new (base + unitOf[size_t(c)] * kUnit)
        TraversalCell{{g.elo[0], g.elo[1], g.elo[2]}, {g.ehi[0], g.ehi[1], g.ehi[2]}, n, uint32_t(c)};
    auto* blocks = reinterpret_cast<unsigned char*>(cell + 1);
    for (uint32_t k = 0; k < (n + kLanes - 1) / kLanes; ++k) {
      TriangleBlock& b = *new (blocks + k * sizeof(TriangleBlock)) TriangleBlock;
      for (uint32_t lane = 0; lane < uint32_t(kLanes); ++lane) {
        const uint32_t tri = refs_[g.refBegin + std::min(k * kLanes + lane, n - 1)];  // spare lanes: the last triangle again
        const glm::uvec3 ix = scene_->triangles[tri];
        const glm::vec3 p[3] = {scene_->positions[ix.x], scene_->positions[ix.y], scene_->positions[ix.z]};
        for (int vtx = 0; vtx < 3; ++vtx)
          for (int axis = 0; axis < 3; ++axis) b.v[vtx][axis][lane] = p[vtx][axis];
        b.id[lane] = tri;
      }
    }
  });
  // The builder's voxel map is derivable from what the traversal keeps: cellAt reads the cell id
  // from the record a leaf points at.
  std::vector<uint32_t>().swap(leaf_);
  std::vector<uint32_t>().swap(topOffset_);
  std::vector<std::array<uint8_t, 3>>().swap(topDepth_);
}

size_t IrregularGrid::memoryBytes() const {
  return cells_.size() * sizeof(GridCell) + refs_.size() * 4 +
         topCells_.size() * sizeof(TopCell) + walkLeaf_.size() * 4 + walk_.size() * sizeof(Line);
}

}  // namespace lt
