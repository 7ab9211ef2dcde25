#include "layertrace/gpu/gpu_pyramid.h"

#include <algorithm>

#include <epoxy/gl.h>

#include "layertrace/gpu/shader_sources.h"
#include "layertrace/util/error.h"

namespace lt {

size_t GpuPyramid::memoryBytes() const {
  size_t bytes = cells.bytes();
  for (const GpuBuffer& b : offsets) bytes += b.bytes();
  for (const GpuBuffer& b : intervals) bytes += b.bytes();
  return bytes;
}

bool GpuPyramid::fits(const uint32_t* needed) {
  bool ok = true;
  for (int L = 1; L < levels; ++L)
    if (needed[L] > capacity[size_t(L)]) {
      ok = false;
      capacity[size_t(L)] = std::max(needed[L], 2 * capacity[size_t(L)]);
      intervals[size_t(L)] = GpuBuffer(size_t(capacity[size_t(L)]) * sizeof(Interval));
    }
  for (int L = 1; L < levels; ++L) intervalCounts[size_t(L)] = needed[L];
  return ok;
}

namespace {

/// The builder's own conditions, as the CPU builder's (τ = ∞ is the Hi-Z pyramid; the options'
/// finite τ is checked by validatePyramidConfig).
void checkConfig(const PyramidConfig& config) {
  if (config.levels < 1 || config.levels > GpuPyramid::kMaxLevels)
    inputError("--levels ", config.levels, ": must be between 1 and ", GpuPyramid::kMaxLevels);
  if (!(config.tau > 0.0f)) inputError("--tau ", config.tau, ": must be positive");
}

/// The levels' sizes and cell bases; whether they are those `out` already has.
bool layOut(int W, int H, const PyramidConfig& config, GpuPyramid& out) {
  GpuPyramid p;
  p.levels = config.levels;
  p.width[0] = W, p.height[0] = H;
  int cells = 0;
  for (int L = 1; L < config.levels; ++L) {
    p.width[size_t(L)] = (p.width[size_t(L - 1)] + 1) / 2;
    p.height[size_t(L)] = (p.height[size_t(L - 1)] + 1) / 2;
    p.cellBase[size_t(L)] = cells;
    cells += p.width[size_t(L)] * p.height[size_t(L)];
  }
  const bool same = out.levels == p.levels && out.width == p.width && out.height == p.height && out.cells.id() != 0;
  if (!same) {
    out = GpuPyramid{};
    out.levels = p.levels;
    out.width = p.width, out.height = p.height, out.cellBase = p.cellBase;
    out.cells = GpuBuffer(size_t(cells) * sizeof(CoarseCell));
    out.offsets.resize(size_t(config.levels));
    out.intervals.resize(size_t(config.levels));
    out.intervalCounts.assign(size_t(config.levels), 0);
    out.capacity.assign(size_t(config.levels), 0);
  }
  return same;
}

/// One level's counting pass and scan, then (`resident`: into the kept buffer, the total left
/// on the device; else: the total read back and the buffer made to fit) its writing pass.
void buildLevel(GpuContext& gpu, const GpuBuffer& level0, const GpuBuffer& counts, int L, int k, const Camera& camera,
                const PyramidConfig& config, GpuPyramid& out, bool resident, const GpuTimer* timer, double& ms) {
  const GpuProgram& merge = gpu.computeProgram("pyramid_merge.comp", shader_source::pyramid_merge_comp);
  const GpuProgram& scan = gpu.computeProgram("pyramid_scan.comp", shader_source::pyramid_scan_comp);
  const int w = out.width[size_t(L)], h = out.height[size_t(L)];
  const size_t n = size_t(w) * size_t(h);
  if (out.offsets[size_t(L)].bytes() != std::max<size_t>((n + 1) * sizeof(uint32_t), 16))
    out.offsets[size_t(L)] = GpuBuffer((n + 1) * sizeof(uint32_t));
  level0.bindStorage(0), counts.bindStorage(1);
  if (L > 1) out.offsets[size_t(L - 1)].bindStorage(2), out.intervals[size_t(L - 1)].bindStorage(3);
  else level0.bindStorage(2), level0.bindStorage(3);  // unread at level 1
  out.offsets[size_t(L)].bindStorage(4);
  out.cells.bindStorage(6);
  merge.set("uLevel", L);
  merge.set("uK", k);
  merge.set("uWidth", w);
  merge.set("uHeight", h);
  merge.set("uChildWidth", out.width[size_t(L - 1)]);
  merge.set("uChildHeight", out.height[size_t(L - 1)]);
  // τ per unit depth for a 2^L-pixel cell, as the CPU computes it (tauPerDepth).
  merge.set("uTauPerDepth", config.tau * camera.pixelFootprint(1.0f) * float(1 << L));
  merge.set("uCellBase", uint32_t(out.cellBase[size_t(L)]));
  // Count, scan, then (the total known) write.
  if (timer) timer->begin();
  merge.set("uPass", 0);
  out.cells.bindStorage(5);  // unwritten in the counting pass
  gpu.dispatch(merge, n);
  scan.set("uCount", int(n));
  scan.set("uStatusSlot", resident ? L : -1);
  if (resident) out.status.bindStorage(7);
  gpu.dispatchGroups(scan, 1);
  if (!resident) {
    timer->end();
    ms += timer->ms();
    uint32_t total = 0;
    out.offsets[size_t(L)].read(&total, sizeof total, n * sizeof(uint32_t));
    out.intervalCounts[size_t(L)] = total;
    out.capacity[size_t(L)] = total;
    out.intervals[size_t(L)] = GpuBuffer(size_t(total) * sizeof(Interval));
  } else if (out.capacity[size_t(L)] == 0) {
    // Choice: room for 2k intervals per cell on average before the first frame says more.
    out.capacity[size_t(L)] = uint32_t(std::max<size_t>(n * size_t(k) * 2, 16));
    out.intervals[size_t(L)] = GpuBuffer(size_t(out.capacity[size_t(L)]) * sizeof(Interval));
  }
  merge.set("uCapacity", out.capacity[size_t(L)]);
  out.intervals[size_t(L)].bindStorage(5);
  merge.set("uPass", 1);
  if (!resident) timer->begin();
  gpu.dispatch(merge, n);
  if (timer) {
    timer->end();
    if (!resident) ms += timer->ms();
  }
}

}  // namespace

void buildPyramidOnGpu(GpuContext& gpu, const GpuBuffer& level0, const GpuBuffer& counts, int W, int H, int k, const Camera& camera,
                       const PyramidConfig& config, GpuPyramid& out) {
  checkConfig(config);
  gpu.makeCurrent();
  GpuDebugGroup group("pyramid");
  out = GpuPyramid{};
  layOut(W, H, config, out);
  const GpuTimer timer;
  double ms = 0.0;
  for (int L = 1; L < config.levels; ++L) buildLevel(gpu, level0, counts, L, k, camera, config, out, false, &timer, ms);
  glUseProgram(0);
  out.buildMs = ms;
}

void buildPyramidResident(GpuContext& gpu, const GpuBuffer& level0, const GpuBuffer& counts, int W, int H, int k, const Camera& camera,
                          const PyramidConfig& config, GpuPyramid& out) {
  checkConfig(config);
  GpuDebugGroup group("pyramid");
  layOut(W, H, config, out);
  if (!out.status.id()) {
    out.status = GpuBuffer(GpuPyramid::kStatusWords * sizeof(uint32_t));
    out.status.fill(0u);
  }
  double ms = 0.0;
  for (int L = 1; L < config.levels; ++L) buildLevel(gpu, level0, counts, L, k, camera, config, out, true, nullptr, ms);
}

IntervalPyramid downloadPyramid(const GpuPyramid& g) {
  IntervalPyramid p;
  p.levels.resize(size_t(g.levels));
  p.levels[0].width = g.width[0], p.levels[0].height = g.height[0];
  std::vector<CoarseCell> all(g.cells.bytes() / sizeof(CoarseCell));
  if (!all.empty()) g.cells.read(all.data(), all.size() * sizeof(CoarseCell));
  for (int L = 1; L < g.levels; ++L) {
    PyramidLevel& lvl = p.levels[size_t(L)];
    lvl.width = g.width[size_t(L)], lvl.height = g.height[size_t(L)];
    const size_t n = size_t(lvl.width) * size_t(lvl.height);
    lvl.offset.resize(n + 1);
    g.offsets[size_t(L)].read(lvl.offset.data(), (n + 1) * sizeof(uint32_t));
    lvl.intervals.resize(g.intervalCounts[size_t(L)]);
    if (!lvl.intervals.empty()) g.intervals[size_t(L)].read(lvl.intervals.data(), lvl.intervals.size() * sizeof(Interval));
    lvl.cells.resize(n);
    std::copy(all.begin() + g.cellBase[size_t(L)], all.begin() + g.cellBase[size_t(L)] + std::ptrdiff_t(n), lvl.cells.begin());
  }
  p.buildMs = g.buildMs;
  return p;
}

}  // namespace lt
