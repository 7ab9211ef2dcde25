// The same reflection rays as trace_gbuffer.cpp, graded against Embree on the triangles that
// produced the depth buffer: how many hits are right, and why the others are not.
#include <cstdio>

#include "synthetic_gbuffer.h"

int main() {
  const example::GBuffer g = example::makeGBuffer(320, 180);
  const lt::ScreenLayers layers = lt::ScreenLayers::fromDepthBuffer(g.view, g.depth, g.normals);
  const std::vector<lt::Ray> rays = example::reflectionRays(g);
  std::vector<lt::TraceHit> hits(rays.size()), truth(rays.size());
  lt::ScreenTracer(layers, "hssr").trace(rays, hits);

  const lt::TriangleScene scene(g.positions, g.triangles);
  lt::MeshTracer(scene, g.view, "embree-robust").trace(rays, truth);  // the ground truth
  const std::vector<uint8_t> classes = lt::classifyHits(layers, rays, hits, truth);
  size_t count[8] = {};
  for (uint8_t c : classes) ++count[c];
  std::printf("classify_against_embree: %zu rays\n", rays.size());
  for (int c = 0; c < 8; ++c)
    std::printf("  %-22s %6.2f %%\n", lt::hitClassName(lt::HitClass(c)), 100.0 * double(count[c]) / double(rays.size()));
  // A one-layer depth buffer cannot know what is behind the box or off screen: those rays are
  // information misses, not errors of the tracer.
  return count[size_t(lt::HitClass::CorrectHit)] > 0 ? 0 : 1;
}
