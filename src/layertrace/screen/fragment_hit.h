// Turning a stored fragment into a TraceHit: shared by every screen-space tracer.
#pragma once

#include "layertrace/raster/layer_arrays.h"
#include "layertrace/scene/camera.h"
#include "layertrace/trace/tracer.h"

namespace lt {

/// The hit at fragment (x, y, layer): its point is where the pixel-centre ray meets the stored
/// depth (the surface the rasterizer sampled), its attributes are the stored ones.
inline TraceHit fragmentHit(const Camera& camera, const LayerArrays& layers, int x, int y, int layer) {
  const FragmentNode& f = layers.pixel(x, y)[layer];
  TraceHit h;
  h.hit = true;
  h.x = x;
  h.y = y;
  h.layer = layer;
  h.point = camera.rayThrough({float(x) + 0.5f, float(y) + 0.5f}) * f.depth;
  h.normal = decodeOctahedral(f.normal);
  h.albedoSpec = f.albedoSpec;
  h.triangle = layers.triangle[layers.pixelIndex(x, y) * size_t(layers.k) + size_t(layer)];
  return h;
}

}  // namespace lt
