#include "layertrace/geometry/embree_scene.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <limits>

#include <embree3/rtcore.h>
#if defined(__x86_64__) || defined(__i386__)
#include <pmmintrin.h>
#include <xmmintrin.h>
#endif

#include "layertrace/scene/surface.h"
#include "layertrace/util/error.h"
#include "layertrace/util/memory.h"

namespace lt {

namespace {

/// Flush-to-zero and denormals-are-zero while Embree runs (its documentation asks for both, for
/// speed), restored on exit: the calling thread — often the main thread, which TBB also lends to
/// parallel loops — must not keep them, or the caller's own arithmetic on tiny values (a scene
/// scaled to 1e-20, say) silently flushes to zero. One MXCSR read and two writes, as the two
/// _MM_SET_* macros cost before. On aarch64 the one FPCR bit FZ (24) does both; elsewhere nothing.
class FlushDenormalsScope {
 public:
#if defined(__x86_64__) || defined(__i386__)
  FlushDenormalsScope() : saved_(_mm_getcsr()) { _mm_setcsr(unsigned(saved_) | _MM_FLUSH_ZERO_ON | _MM_DENORMALS_ZERO_ON); }
  ~FlushDenormalsScope() { _mm_setcsr(unsigned(saved_)); }
#elif defined(__aarch64__)
  FlushDenormalsScope() {
    asm volatile("mrs %0, fpcr" : "=r"(saved_));
    const uint64_t flush = saved_ | (uint64_t(1) << 24);
    asm volatile("msr fpcr, %0" : : "r"(flush));
  }
  ~FlushDenormalsScope() { asm volatile("msr fpcr, %0" : : "r"(saved_)); }
#else
  FlushDenormalsScope() = default;
#endif
  FlushDenormalsScope(const FlushDenormalsScope&) = delete;
  FlushDenormalsScope& operator=(const FlushDenormalsScope&) = delete;

 private:
  uint64_t saved_ = 0;
};

std::atomic<int64_t> gEmbreeBytes{0};

bool memoryMonitor(void*, ssize_t bytes, bool) {
  gEmbreeBytes += bytes;
  return true;
}

void errorCallback(void*, RTCError code, const char* str) {
  if (code == RTC_ERROR_OUT_OF_MEMORY) return;  // reported by the failing call below
  (void)str;
}

RTCRayHit makeRay(glm::vec3 o, glm::vec3 d, float tnear, float tfar) {
  RTCRayHit rh{};
  rh.ray.org_x = o.x, rh.ray.org_y = o.y, rh.ray.org_z = o.z;
  rh.ray.dir_x = d.x, rh.ray.dir_y = d.y, rh.ray.dir_z = d.z;
  rh.ray.tnear = tnear;
  rh.ray.tfar = tfar;
  rh.ray.mask = 0xFFFFFFFFu;
  rh.ray.flags = 0;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
  return rh;
}

/// Intersect context whose filter records every hit and rejects it, so traversal continues.
struct CollectContext {
  RTCIntersectContext base;
  std::vector<GeoHit>* out;
};

void collectFilter(const RTCFilterFunctionNArguments* args) {
  auto* ctx = reinterpret_cast<const CollectContext*>(args->context);
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] == 0) continue;
    GeoHit h;
    h.t = RTCRayN_tfar(args->ray, args->N, i);
    h.triangle = RTCHitN_primID(args->hit, args->N, i);
    h.ng = {RTCHitN_Ng_x(args->hit, args->N, i), RTCHitN_Ng_y(args->hit, args->N, i), RTCHitN_Ng_z(args->hit, args->N, i)};
    ctx->out->push_back(h);
    args->valid[i] = 0;  // reject: keep looking
  }
}

/// Alpha-tested triangles (Scene::cutOut): a hit where surfacePresent says the texel is cut away
/// is rejected, so traversal goes on behind it. Embree's (u, v) are the weights of the second and
/// third vertex, surfacePresent's (b1, b2). The geometry's user data is the scene it reads.
void rejectCutAway(const RTCFilterFunctionNArguments* args) {
  const auto* scene = static_cast<const Scene*>(args->geometryUserPtr);
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] == 0) continue;
    const uint32_t tri = RTCHitN_primID(args->hit, args->N, i);
    if (scene->cutOut(tri) && !surfacePresent(*scene, tri, RTCHitN_u(args->hit, args->N, i), RTCHitN_v(args->hit, args->N, i)))
      args->valid[i] = 0;
  }
}

/// Capture mode with cut-outs: the alpha test, then the all-hit collection of what remains.
void rejectCutAwayThenCollect(const RTCFilterFunctionNArguments* args) {
  rejectCutAway(args);
  collectFilter(args);
}

}  // namespace

struct EmbreeScene::Impl {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  int64_t bytes = 0;
  /// What the alpha test reads (triangles, materials, texture coordinates and textures; no
  /// positions), kept here so that the filter does not depend on the caller's scene living on.
  Scene cutOuts;
  ~Impl() {
    if (scene) rtcReleaseScene(scene);
    if (device) rtcReleaseDevice(device);
  }
};

EmbreeScene::EmbreeScene(const Scene& scene, Mode mode) : impl_(std::make_unique<Impl>()), mode_(mode) {
  const auto start = std::chrono::steady_clock::now();
  const FlushDenormalsScope denormals;
  // Embree's BVH takes about 100 bytes per triangle here (HIGH quality; measured, see
  // docs/methods/grid.md): refuse up front with room to spare rather than fail inside the build.
  checkAllocation(cat("the Embree BVH (", scene.triangleCount(), " triangles)"),
                  uint64_t(scene.triangleCount()) * 192 + uint64_t(scene.positions.size()) * 16);
  const int64_t before = gEmbreeBytes.load();
  impl_->device = rtcNewDevice("threads=0");
  if (!impl_->device) throw InternalError("embree: cannot create device");
  rtcSetDeviceErrorFunction(impl_->device, errorCallback, nullptr);
  rtcSetDeviceMemoryMonitorFunction(impl_->device, memoryMonitor, nullptr);
  impl_->scene = rtcNewScene(impl_->device);
  if (mode == Mode::Robust) rtcSetSceneFlags(impl_->scene, RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION | RTC_SCENE_FLAG_ROBUST);
  rtcSetSceneBuildQuality(impl_->scene, RTC_BUILD_QUALITY_HIGH);
  RTCGeometry geom = rtcNewGeometry(impl_->device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                        3 * sizeof(float), scene.positions.size()));
  auto* idx = static_cast<uint32_t*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                             3 * sizeof(uint32_t), scene.triangles.size()));
  if (!v || !idx) throw InternalError("embree: cannot allocate geometry buffers");
  for (size_t i = 0; i < scene.positions.size(); ++i)
    v[3 * i] = scene.positions[i].x, v[3 * i + 1] = scene.positions[i].y, v[3 * i + 2] = scene.positions[i].z;
  for (size_t i = 0; i < scene.triangles.size(); ++i)
    idx[3 * i] = scene.triangles[i].x, idx[3 * i + 1] = scene.triangles[i].y, idx[3 * i + 2] = scene.triangles[i].z;
  // Capture mode: the all-hit filter on the geometry (no scene flag needed); allHits passes the
  // collecting context, other queries never run on this scene.
  // Geometry filters run before a context's filter (allHits in robust mode collects in the
  // context filter, so it sees only hits the alpha test kept).
  if (scene.anyCutOut()) {
    Scene& cut = impl_->cutOuts;
    cut.triangles = scene.triangles, cut.triMaterial = scene.triMaterial, cut.materials = scene.materials;
    cut.texcoords = scene.texcoords, cut.textures = scene.textures;
    rtcSetGeometryUserData(geom, &cut);
    rtcSetGeometryIntersectFilterFunction(geom, mode == Mode::Capture ? rejectCutAwayThenCollect : rejectCutAway);
    rtcSetGeometryOccludedFilterFunction(geom, rejectCutAway);
  } else if (mode == Mode::Capture) {
    rtcSetGeometryIntersectFilterFunction(geom, collectFilter);
  }
  rtcCommitGeometry(geom);
  rtcAttachGeometry(impl_->scene, geom);
  rtcReleaseGeometry(geom);
  rtcCommitScene(impl_->scene);
  if (rtcGetDeviceError(impl_->device) != RTC_ERROR_NONE) throw InternalError("embree: scene build failed");
  impl_->bytes = gEmbreeBytes.load() - before;
  buildMs_ = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

EmbreeScene::~EmbreeScene() = default;

size_t EmbreeScene::memoryBytes() const { return size_t(std::max<int64_t>(impl_->bytes, 0)); }

GeoHit EmbreeScene::intersect(glm::vec3 o, glm::vec3 d, float tnear, float tfar, TraversalCounts* counts) const {
  const FlushDenormalsScope denormals;
  if (counts) ++counts->steps;
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RTCRayHit rh = makeRay(o, d, tnear, tfar);
  rtcIntersect1(impl_->scene, &ctx, &rh);
  GeoHit h;
  if (rh.hit.geomID != RTC_INVALID_GEOMETRY_ID) {
    h.t = rh.ray.tfar;
    h.triangle = rh.hit.primID;
    h.ng = {rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z};
  }
  return h;
}

bool EmbreeScene::occluded(glm::vec3 o, glm::vec3 d, float tnear, float tfar, TraversalCounts* counts) const {
  const FlushDenormalsScope denormals;
  if (counts) ++counts->steps;
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RTCRay r = makeRay(o, d, tnear, tfar).ray;
  rtcOccluded1(impl_->scene, &ctx, &r);
  return r.tfar < 0.0f;  // Embree sets tfar = -inf on occlusion
}

namespace {

/// rtcIntersect4/8/16 on one packet of N rays.
template <int N, class RayHitN>
void intersectPacket(RTCScene scene, const glm::vec3* o, const glm::vec3* d, int n, const float* tnear, const float* tfar, GeoHit* out) {
  alignas(64) int valid[N];
  alignas(64) RayHitN rh{};
  for (int i = 0; i < N; ++i) {
    const int j = i < n ? i : 0;
    valid[i] = i < n ? -1 : 0;
    rh.ray.org_x[i] = o[j].x, rh.ray.org_y[i] = o[j].y, rh.ray.org_z[i] = o[j].z;
    rh.ray.dir_x[i] = d[j].x, rh.ray.dir_y[i] = d[j].y, rh.ray.dir_z[i] = d[j].z;
    rh.ray.tnear[i] = tnear[j], rh.ray.tfar[i] = tfar[j];
    rh.ray.mask[i] = 0xFFFFFFFFu, rh.ray.flags[i] = 0;
    rh.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
  }
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  if constexpr (N == 4) rtcIntersect4(valid, scene, &ctx, &rh);
  else if constexpr (N == 8) rtcIntersect8(valid, scene, &ctx, &rh);
  else rtcIntersect16(valid, scene, &ctx, &rh);
  for (int i = 0; i < n; ++i) {
    out[i] = GeoHit{};
    if (rh.hit.geomID[i] == RTC_INVALID_GEOMETRY_ID) continue;
    out[i].t = rh.ray.tfar[i];
    out[i].triangle = rh.hit.primID[i];
    out[i].ng = {rh.hit.Ng_x[i], rh.hit.Ng_y[i], rh.hit.Ng_z[i]};
  }
}

/// rtcOccluded16 on one packet of n ≤ 16 rays.
void occludedPacket(RTCScene scene, const glm::vec3* o, const glm::vec3* d, int n, const float* tnear, const float* tfar, bool* out) {
  alignas(64) int valid[16];
  alignas(64) RTCRay16 r{};
  for (int i = 0; i < 16; ++i) {
    const int j = i < n ? i : 0;
    valid[i] = i < n ? -1 : 0;
    r.org_x[i] = o[j].x, r.org_y[i] = o[j].y, r.org_z[i] = o[j].z;
    r.dir_x[i] = d[j].x, r.dir_y[i] = d[j].y, r.dir_z[i] = d[j].z;
    r.tnear[i] = tnear[j], r.tfar[i] = tfar[j];
    r.mask[i] = 0xFFFFFFFFu, r.flags[i] = 0;
  }
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  rtcOccluded16(valid, scene, &ctx, &r);
  for (int i = 0; i < n; ++i) out[i] = r.tfar[i] < 0.0f;  // Embree sets tfar = -inf on occlusion
}

}  // namespace

void EmbreeScene::occludedPackets(const glm::vec3* o, const glm::vec3* d, const float* tnear, const float* tfar, size_t n,
                                  bool* out) const {
  const FlushDenormalsScope denormals;
  for (size_t b = 0; b < n; b += 16) occludedPacket(impl_->scene, o + b, d + b, int(std::min<size_t>(16, n - b)), tnear + b, tfar + b, out + b);
}

void EmbreeScene::intersectPackets(const glm::vec3* o, const glm::vec3* d, size_t n, float tnear, float tfar, int width,
                                   GeoHit* out) const {
  float nears[16], fars[16];
  std::fill(nears, nears + 16, tnear);
  std::fill(fars, fars + 16, tfar);
  const FlushDenormalsScope denormals;
  for (size_t b = 0; b < n; b += size_t(width)) {
    const int m = int(std::min<size_t>(size_t(width), n - b));
    if (width == 4) intersectPacket<4, RTCRayHit4>(impl_->scene, o + b, d + b, m, nears, fars, out + b);
    else if (width == 8) intersectPacket<8, RTCRayHit8>(impl_->scene, o + b, d + b, m, nears, fars, out + b);
    else intersectPacket<16, RTCRayHit16>(impl_->scene, o + b, d + b, m, nears, fars, out + b);
  }
}

void EmbreeScene::intersectPackets(const glm::vec3* o, const glm::vec3* d, const float* tnear, const float* tfar, size_t n,
                                   GeoHit* out) const {
  const FlushDenormalsScope denormals;
  for (size_t b = 0; b < n; b += 16)
    intersectPacket<16, RTCRayHit16>(impl_->scene, o + b, d + b, int(std::min<size_t>(16, n - b)), tnear + b, tfar + b, out + b);
}

void EmbreeScene::allHits(glm::vec3 o, glm::vec3 d, float tnear, float tfar, std::vector<GeoHit>& out) const {
  if (mode_ == Mode::Fast) throw InternalError("embree: allHits needs a scene built in robust or capture mode");
  const FlushDenormalsScope denormals;
  out.clear();
  CollectContext ctx;
  rtcInitIntersectContext(&ctx.base);
  if (mode_ == Mode::Robust) ctx.base.filter = collectFilter;
  ctx.out = &out;
  RTCRayHit rh = makeRay(o, d, tnear, tfar);
  rtcIntersect1(impl_->scene, &ctx.base, &rh);
  std::sort(out.begin(), out.end(), [](const GeoHit& a, const GeoHit& b) {
    return a.triangle != b.triangle ? a.triangle < b.triangle : a.t < b.t;
  });
  out.erase(std::unique(out.begin(), out.end(), [](const GeoHit& a, const GeoHit& b) { return a.triangle == b.triangle; }),
            out.end());
  std::sort(out.begin(), out.end(), [](const GeoHit& a, const GeoHit& b) { return a.t < b.t; });
}

}  // namespace lt
