// Embree behind the tracer interface: the geometric answer for the very rays the screen-space
// tracers trace (same camera-space origins and directions).
#pragma once

#include "layertrace/geometry/embree_scene.h"
#include "layertrace/scene/camera.h"
#include "layertrace/screen/tracer.h"

namespace lt {

class EmbreeTracer : public Tracer {
 public:
  EmbreeTracer(const Scene& scene, const Camera& camera, const EmbreeScene& embree);
  const char* name() const override { return "embree"; }
  TraceHit trace(const ScreenRay& ray, RayCounters& counters) const override;

 private:
  const Scene& scene_;
  const Camera& camera_;
  const EmbreeScene& embree_;
  std::vector<uint32_t> packed_;  ///< per material: albedo + specular as stored in fragments
};

}  // namespace lt
