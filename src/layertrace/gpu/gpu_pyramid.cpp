#include "layertrace/gpu/gpu_pyramid.h"

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

void buildPyramidOnGpu(GpuContext& gpu, const GpuBuffer& level0, const GpuBuffer& counts, int W, int H, int k, const Camera& camera,
                       const PyramidConfig& config, GpuPyramid& out) {
  // The builder's own conditions, as the CPU builder's (τ = ∞ is the Hi-Z pyramid; the
  // options' finite τ is checked by validatePyramidConfig).
  if (config.levels < 1 || config.levels > GpuPyramid::kMaxLevels)
    inputError("--levels ", config.levels, ": must be between 1 and ", GpuPyramid::kMaxLevels);
  if (!(config.tau > 0.0f)) inputError("--tau ", config.tau, ": must be positive");
  gpu.makeCurrent();
  out = GpuPyramid{};
  out.levels = config.levels;
  out.width[0] = W, out.height[0] = H;
  size_t cells = 0;
  for (int L = 1; L < config.levels; ++L) {
    out.width[size_t(L)] = (out.width[size_t(L - 1)] + 1) / 2;
    out.height[size_t(L)] = (out.height[size_t(L - 1)] + 1) / 2;
    out.cellBase[size_t(L)] = int(cells);
    cells += size_t(out.width[size_t(L)]) * size_t(out.height[size_t(L)]);
  }
  out.cells = GpuBuffer(cells * sizeof(CoarseCell));
  out.offsets.resize(size_t(config.levels));
  out.intervals.resize(size_t(config.levels));
  out.intervalCounts.assign(size_t(config.levels), 0);
  const GpuProgram merge = gpu.computeProgram("pyramid_merge.comp", shader_source::pyramid_merge_comp);
  const GpuProgram scan = gpu.computeProgram("pyramid_scan.comp", shader_source::pyramid_scan_comp);
  const GpuTimer timer;
  double ms = 0.0;
  for (int L = 1; L < config.levels; ++L) {
    const int w = out.width[size_t(L)], h = out.height[size_t(L)];
    const size_t n = size_t(w) * size_t(h);
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
    timer.begin();
    merge.set("uPass", 0);
    out.cells.bindStorage(5);  // unwritten in the counting pass
    gpu.dispatch(merge, n);
    scan.set("uCount", int(n));
    glUseProgram(scan.id());
    glDispatchCompute(1, 1, 1);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_BUFFER_UPDATE_BARRIER_BIT);
    timer.end();
    ms += timer.ms();
    uint32_t total = 0;
    out.offsets[size_t(L)].read(&total, sizeof total, n * sizeof(uint32_t));
    out.intervalCounts[size_t(L)] = total;
    out.intervals[size_t(L)] = GpuBuffer(size_t(total) * sizeof(Interval));
    out.intervals[size_t(L)].bindStorage(5);
    merge.set("uPass", 1);
    timer.begin();
    gpu.dispatch(merge, n);
    timer.end();
    ms += timer.ms();
  }
  glUseProgram(0);
  out.buildMs = ms;
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
