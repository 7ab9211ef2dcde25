#include "layertrace/gpu/gpu_ray_batch.h"

#include <algorithm>

#include "layertrace/util/default_init.h"
#include "layertrace/util/error.h"
#include "layertrace/util/parallel.h"

namespace lt {

namespace {
/// shaders/ray_io.glsl GpuRay, std430: camera-space origin and maximum distance, direction and
/// 1 when the ray starts on a stored surface.
struct RayRecord {
  float origin[3], maxDistance;
  float dir[3], startsOnSurface;
};
static_assert(sizeof(RayRecord) == 32);

}  // namespace

void reserve(GpuBuffer& buffer, size_t bytes) {
  if (buffer.bytes() < bytes) buffer = GpuBuffer(std::max(bytes, 2 * buffer.bytes()));
}

void GpuRayBatch::upload(std::span<const Ray> rays) {
  PoolVector<RayRecord> records(rays.size());
  parallelFor(size_t(0), rays.size(), [&](size_t i) {
    const Ray& r = rays[i];
    records[i] = {{r.origin.x, r.origin.y, r.origin.z}, r.maxDistance, {r.dir.x, r.dir.y, r.dir.z}, r.startsOnSurface ? 1.0f : 0.0f};
  });
  const size_t bytes = records.size() * sizeof(RayRecord);
  reserve(rays_, bytes);
  rays_.write(records.data(), bytes);
}

const GpuBuffer& GpuRayBatch::answers(int slot, size_t bytes) {
  LT_CHECK(slot >= 0 && slot < kAnswerBuffers, slot);
  reserve(answers_[slot], bytes);
  return answers_[slot];
}

}  // namespace lt
