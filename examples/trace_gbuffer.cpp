// From a depth buffer you already have to traced reflection hits: one ScreenLayers, one
// ScreenTracer. Prints hit statistics and writes trace_gbuffer.png (what each pixel's reflection
// ray hit, coloured by its normal; black where it found nothing).
#include <cstdio>

#include "synthetic_gbuffer.h"

int main(int argc, char** argv) {
  const example::GBuffer g = example::makeGBuffer(320, 180);
  const lt::ScreenLayers layers = lt::ScreenLayers::fromDepthBuffer(g.view, g.depth, g.normals);
  const lt::ScreenTracer hssr(layers, "hssr");
  const std::vector<lt::Ray> rays = example::reflectionRays(g);
  std::vector<lt::TraceHit> hits(rays.size());
  hssr.trace(rays, hits);

  size_t hitCount = 0;
  lt::RgbImage image;
  image.width = g.view.width, image.height = g.view.height;
  image.rgb.assign(size_t(image.width) * size_t(image.height) * 3, 0.0f);
  size_t ray = 0;
  for (size_t p = 0; p < g.depth.size(); ++p) {
    if (!std::isfinite(g.depth[p])) continue;
    const lt::TraceHit& h = hits[ray++];
    if (!h.hit) continue;
    ++hitCount;
    for (int c = 0; c < 3; ++c) image.rgb[p * 3 + size_t(c)] = 0.5f + 0.5f * h.normal[c];
  }
  std::printf("trace_gbuffer: %zu reflection rays, %zu hits (%.1f %%)\n", rays.size(), hitCount,
              rays.empty() ? 0.0 : 100.0 * double(hitCount) / double(rays.size()));
  image.savePng(argc > 1 ? argv[1] : "trace_gbuffer.png");
  return hitCount > 0 ? 0 : 1;
}
