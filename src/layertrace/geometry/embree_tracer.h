// Geometric tracers behind the tracer interface: the answer of Embree or of the irregular grid
// for the very rays the screen-space tracers trace (same camera-space origins and directions).
#pragma once

#include <functional>
#include <memory>

#include "layertrace/geometry/embree_scene.h"
#include "layertrace/geometry/irregular_grid.h"
#include "layertrace/scene/camera.h"
#include "layertrace/screen/tracer.h"

namespace lt {

class GeometricTracer : public Tracer {
 public:
  /// World-space closest-hit query: origin, direction, tnear, tfar, visited cells (may be null).
  using Query = std::function<GeoHit(glm::vec3, glm::vec3, float, float, uint32_t*)>;
  GeometricTracer(const char* name, const Scene& scene, const Camera& camera, Query query);
  const char* name() const override { return name_; }
  TraceHit trace(const ScreenRay& ray, RayCounters& counters) const override;

 private:
  const char* name_;
  const Scene& scene_;
  const Camera& camera_;
  Query query_;
  std::vector<uint32_t> packed_;  ///< per material: albedo + specular as stored in fragments
};

/// Embree as a tracer ("embree").
std::unique_ptr<Tracer> makeEmbreeTracer(const Scene& scene, const Camera& camera, const EmbreeScene& embree);
/// The irregular grid as a tracer ("grid"); iterations count visited cells.
std::unique_ptr<Tracer> makeGridTracer(const Scene& scene, const Camera& camera, const IrregularGrid& grid);

}  // namespace lt
