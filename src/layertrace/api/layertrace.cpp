// The public API (api/layertrace.h) on top of the library's layers: user buffers become a
// pipeline Frame's k-layer arrays, tracers are built by name as the CLI builds them, and every
// internal error is translated at this boundary into the standard exceptions the header promises.
#include "layertrace/api/layertrace.h"
#include "layertrace/api/api_detail.h"

#include <cmath>
#include <limits>
#include <stdexcept>

#include <glm/geometric.hpp>

#include "layertrace/eval/classify.h"
#include "layertrace/pipeline/frame.h"
#include "layertrace/pipeline/tracer_registry.h"
#include "layertrace/render/effects.h"
#include "layertrace/util/error.h"
#include "layertrace/util/image.h"

namespace lt {

using namespace api_detail;

struct ScreenLayers::Impl {
  View view;
  Frame frame;  ///< camera and k-layer arrays (no scene: screen tracers read only these)
};
struct ScreenTracer::Impl {
  const ScreenLayers::Impl* layers;
  BuiltTracer built;
};
struct MeshTracer::Impl {
  Frame frame;  ///< the scene (a copy) and the view's camera
  BuiltTracer built;
};

namespace api_detail {

const TracerParam& paramNamed(const std::string& name) {
  for (const TracerParam& p : tracerParams())
    if (name == p.flag + 2 || (*p.alias && name == p.alias + 2)) return p;
  invalid(cat("parameter \"", name, "\": unknown (layertrace tracers lists every parameter)"));
}

TracerOptions tracerOptions(const TracerParams& params) {
  return guarded([&] {
    TracerOptions o = presetOptions(params.preset());
    o.preset = params.preset();
    for (const auto& [name, value] : params.values()) setParamValue(paramNamed(name), o, value);
    return o;
  });
}

Camera cameraOf(const View& v) {
  if (v.width < 1 || v.height < 1 || v.width > 32768 || v.height > 32768)
    invalid(cat("view.width/height ", v.width, "x", v.height, ": must be 1..32768 each"));
  if (!(v.fovY > 0.0f && v.fovY < 180.0f)) invalid(cat("view.fovY ", v.fovY, ": must be in (0, 180) degrees"));
  if (!(v.near > 0.0f) || !std::isfinite(v.near)) invalid(cat("view.near ", v.near, ": must be positive"));
  if (!(v.far > v.near) || !std::isfinite(v.far)) invalid(cat("view.far ", v.far, ": must be beyond view.near ", v.near));
  for (const glm::vec3& p : {v.eye, v.target, v.up})
    if (!std::isfinite(p.x + p.y + p.z)) invalid("view: eye, target and up must be finite");
  CameraDesc d;
  d.name = "user";
  d.eye = v.eye, d.target = v.target, d.up = v.up, d.fovY = v.fovY, d.near = v.near, d.far = v.far;
  return guarded([&] { return Camera(d, v.width, v.height); });
}

float thicknessPerDepth(const Camera& camera, float thicknessPx) {
  if (!(thicknessPx > 0.0f) || !std::isfinite(thicknessPx)) invalid(cat("thicknessPx ", thicknessPx, ": must be positive"));
  return thicknessPx / camera.focal();
}

}  // namespace api_detail

namespace {

void expectSize(const char* what, size_t size, size_t expected, bool optional) {
  if ((optional && size == 0) || size == expected) return;
  invalid(cat(what, ": ", size, " elements, expected ", expected, optional ? " (or none)" : ""));
}

glm::vec3 normalOr(std::span<const glm::vec3> normals, size_t i, const char* what) {
  if (normals.empty()) return {0.0f, 0.0f, 1.0f};  // facing the camera
  const glm::vec3 n = normals[i];
  const float len = glm::length(n);
  if (!(len > 0.0f) || !std::isfinite(len)) invalid(cat(what, "[", i, "]: not a finite non-zero normal"));
  return n / len;
}

std::unique_ptr<ScreenLayers::Impl> emptyLayers(const View& view, int k) {
  auto impl = std::make_unique<ScreenLayers::Impl>();
  impl->view = view;
  impl->frame.camera = cameraOf(view);
  LayerArrays& L = impl->frame.layers;
  L.width = view.width, L.height = view.height, L.k = k;
  const size_t pixels = size_t(view.width) * size_t(view.height);
  guarded([&] { checkAllocation("the k-layer arrays", pixels * size_t(k) * (sizeof(FragmentNode) + 4) + pixels); });
  L.slots.assign(pixels * size_t(k), FragmentNode{});
  L.count.assign(pixels, 0);
  L.triangle.assign(pixels * size_t(k), 0xFFFFFFFFu);
  return impl;
}

/// Camera-space ray of `view` from a ray in `space`, and the hit back into it.
Ray toCamera(const Camera& c, const Ray& r, RaySpace space) {
  if (space == RaySpace::Camera) return r;
  Ray out = r;
  out.origin = c.toCamera(r.origin);
  out.dir = c.dirToCamera(r.dir);
  return out;
}
void hitsToSpace(const Camera& c, std::span<TraceHit> hits, RaySpace space) {
  if (space == RaySpace::Camera) return;
  for (TraceHit& h : hits)
    if (h.hit) h.point = c.toWorld(h.point), h.normal = c.dirToWorld(h.normal);
}

void traceIn(const Tracer& tracer, const Camera& camera, Query q, std::span<const Ray> rays, std::span<TraceHit> hits, RaySpace space) {
  if (rays.size() != hits.size()) invalid(cat("hits: ", hits.size(), " elements for ", rays.size(), " rays"));
  for (size_t i = 0; i < rays.size(); ++i) {
    const Ray& r = rays[i];
    const float len = glm::length(r.dir);
    if (!std::isfinite(r.origin.x + r.origin.y + r.origin.z) || !(std::abs(len - 1.0f) < 1e-3f))
      invalid(cat("rays[", i, "]: origin must be finite and dir of unit length (length ", len, ")"));
    if (!(r.maxDistance > 0.0f)) invalid(cat("rays[", i, "].maxDistance ", r.maxDistance, ": must be positive"));
  }
  guarded([&] {
    if (space == RaySpace::Camera) {
      tracer.query(q, rays, hits, {});
    } else {
      std::vector<Ray> cam(rays.size());
      for (size_t i = 0; i < rays.size(); ++i) cam[i] = toCamera(camera, rays[i], space);
      tracer.query(q, cam, hits, {});
    }
  });
  hitsToSpace(camera, hits, space);
}

}  // namespace

glm::vec3 worldToCamera(const View& view, glm::vec3 p) { return cameraOf(view).toCamera(p); }
glm::vec3 cameraToWorld(const View& view, glm::vec3 p) { return cameraOf(view).toWorld(p); }
glm::vec3 pixelDirection(const View& view, float px, float py) { return glm::normalize(cameraOf(view).rayThrough({px, py})); }

// ---- ScreenLayers ----------------------------------------------------------------------------

ScreenLayers::ScreenLayers(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
ScreenLayers::ScreenLayers(ScreenLayers&&) noexcept = default;
ScreenLayers& ScreenLayers::operator=(ScreenLayers&&) noexcept = default;
ScreenLayers::~ScreenLayers() = default;
const View& ScreenLayers::view() const { return impl_->view; }
int ScreenLayers::layers() const { return impl_->frame.layers.k; }
int ScreenLayers::countAt(int x, int y) const {
  const LayerArrays& L = impl_->frame.layers;
  if (x < 0 || y < 0 || x >= L.width || y >= L.height) invalid(cat("countAt(", x, ", ", y, "): outside the ", L.width, "x", L.height, " view"));
  return L.countAt(x, y);
}

ScreenLayers ScreenLayers::fromLayers(const View& view, int k, std::span<const float> front, std::span<const float> back,
                                      std::span<const glm::vec3> normals, std::span<const uint32_t> ids) {
  if (k < 1 || k > 16) invalid(cat("k ", k, ": must be between 1 and 16"));
  auto impl = emptyLayers(view, k);
  const size_t pixels = size_t(view.width) * size_t(view.height), n = pixels * size_t(k);
  expectSize("front", front.size(), n, false);
  expectSize("back", back.size(), n, false);
  expectSize("normals", normals.size(), n, true);
  expectSize("ids", ids.size(), n, true);
  LayerArrays& L = impl->frame.layers;
  for (size_t p = 0; p < pixels; ++p) {
    int count = 0;
    for (int l = 0; l < k; ++l) {
      const size_t i = size_t(l) * pixels + p;
      const float f = front[i], b = back[i];
      if (f == std::numeric_limits<float>::infinity()) continue;
      if (count < l) invalid(cat("front[", i, "] = ", f, ": layer ", l, " of pixel ", p, " follows an empty layer"));
      if (!(f > 0.0f) || !std::isfinite(f)) invalid(cat("front[", i, "] = ", f, ": depths must be positive and finite (+inf = empty)"));
      if (!(b >= f) || !std::isfinite(b)) invalid(cat("back[", i, "] = ", b, ": must be finite and not in front of front = ", f));
      if (l > 0 && f < front[i - pixels]) invalid(cat("front[", i, "] = ", f, ": layers of pixel ", p, " are not sorted (layer ", l - 1, " starts at ", front[i - pixels], ")"));
      FragmentNode& node = L.slots[p * size_t(k) + size_t(l)];
      node.depth = f;
      node.normal = encodeOctahedral(normalOr(normals, i, "normals"));
      node.albedoSpec = 0;
      node.setThickness(b - f);
      if (!ids.empty()) L.triangle[p * size_t(k) + size_t(l)] = ids[i];
      ++count;
    }
    L.count[p] = uint8_t(count);
  }
  return ScreenLayers(std::move(impl));
}

ScreenLayers ScreenLayers::fromDepthBuffer(const View& view, std::span<const float> depth, std::span<const glm::vec3> normals,
                                           float thicknessPx) {
  const Camera camera = cameraOf(view);
  const float perDepth = thicknessPerDepth(camera, thicknessPx);
  std::vector<float> back(depth.begin(), depth.end());
  for (float& b : back)
    if (std::isfinite(b)) b += perDepth * b;
  return fromLayers(view, 1, depth, back, normals, {});
}

ScreenLayers ScreenLayers::fromFragments(const View& view, std::span<const uint32_t> offsets, std::span<const float> depth,
                                         std::span<const glm::vec3> normals, std::span<const uint32_t> ids, int k, float thicknessPx) {
  if (k < 1 || k > 16) invalid(cat("k ", k, ": must be between 1 and 16"));
  auto impl = emptyLayers(view, k);
  const size_t pixels = size_t(view.width) * size_t(view.height);
  expectSize("offsets", offsets.size(), pixels + 1, false);
  if (offsets[0] != 0) invalid(cat("offsets[0] = ", offsets[0], ": must be 0"));
  for (size_t p = 0; p < pixels; ++p)
    if (offsets[p + 1] < offsets[p]) invalid(cat("offsets[", p + 1, "] = ", offsets[p + 1], ": less than offsets[", p, "] = ", offsets[p]));
  expectSize("depth", depth.size(), offsets[pixels], false);
  expectSize("normals", normals.size(), depth.size(), true);
  expectSize("ids", ids.size(), depth.size(), true);
  // As the rasterizer leaves them: per-pixel lists of 16-byte nodes, then the sort of
  // Hofmann et al. 2017, §4.2.
  FragmentLists lists;
  lists.width = view.width, lists.height = view.height;
  lists.head.assign(pixels, kNullIndex);
  lists.complexity.assign(pixels, 0);
  lists.nodes.resize(depth.size());
  lists.triangle.resize(depth.size());
  for (size_t p = 0; p < pixels; ++p)
    for (uint32_t i = offsets[p + 1]; i-- > offsets[p];) {  // pushed in reverse: the list runs in input order
      if (!(depth[i] > 0.0f) || !std::isfinite(depth[i])) invalid(cat("depth[", i, "] = ", depth[i], ": must be positive and finite"));
      FragmentNode& f = lists.nodes[i];
      f.depth = depth[i];
      f.normal = encodeOctahedral(normalOr(normals, i, "normals"));
      f.albedoSpec = 0;
      f.next = lists.head[p];
      lists.head[p] = i;
      lists.triangle[i] = ids.empty() ? 0xFFFFFFFFu : ids[i];
      ++lists.complexity[p];
    }
  lists.generated = lists.stored = depth.size();
  LayerConfig lc;
  lc.k = k;
  lc.thickness = 0.0f;
  lc.thicknessPerDepth = thicknessPerDepth(impl->frame.camera, thicknessPx);
  impl->frame.layers = guarded([&] { return sortAndTruncate(lists, lc); });
  return ScreenLayers(std::move(impl));
}

// ---- ScreenTracer ----------------------------------------------------------------------------

// ---- TracerParams ----------------------------------------------------------------------------

TracerParams::TracerParams(const std::string& preset) : preset_(preset) {
  guarded([&] { (void)presetOptions(preset); });  // the CLI's message for an unknown preset
}

TracerParams& TracerParams::set(const std::string& name, const std::string& value) {
  const TracerParam& p = paramNamed(name);
  guarded([&] {
    TracerOptions scratch;
    setParamValue(p, scratch, value);  // checks the value as the CLI does
    validateTracerOptions(scratch);
  });
  const std::string canonical = p.flag + 2;
  for (auto& [n, v] : values_)
    if (n == canonical) {
      v = value;
      return *this;
    }
  values_.emplace_back(canonical, value);
  return *this;
}

std::string TracerParams::get(const std::string& name) const {
  const TracerParam& p = paramNamed(name);
  for (const auto& [n, v] : values_)
    if (n == p.flag + 2) return v;
  return guarded([&] { return paramValue(p, presetOptions(preset_)); });
}

std::vector<std::string> TracerParams::names() {
  std::vector<std::string> out;
  for (const TracerParam& p : tracerParams()) out.emplace_back(p.flag + 2);
  return out;
}

ScreenTracer::ScreenTracer(const ScreenLayers& layers, const std::string& name, const TracerParams& params)
    : impl_(std::make_unique<Impl>()) {
  if (!isScreenTracer(name)) invalid(cat("tracer \"", name, "\": not a screen tracer (use hssr, hiz, ssr, ssr-layers or quadtree)"));
  impl_->layers = &layers.impl();
  const TracerOptions options = tracerOptions(params);
  impl_->built = guarded([&] {
    validateTracerOptions(options);
    return buildTracer(name, layers.impl().frame, options);
  });
}
ScreenTracer::ScreenTracer(ScreenTracer&&) noexcept = default;
ScreenTracer::~ScreenTracer() = default;
const char* ScreenTracer::name() const { return impl_->built.tracer->name(); }
void ScreenTracer::trace(std::span<const Ray> rays, std::span<TraceHit> hits, RaySpace space) const {
  traceIn(*impl_->built.tracer, impl_->layers->frame.camera, Query::Closest, rays, hits, space);
}
void ScreenTracer::occluded(std::span<const Ray> rays, std::span<TraceHit> hits, RaySpace space) const {
  traceIn(*impl_->built.tracer, impl_->layers->frame.camera, Query::Any, rays, hits, space);
}

// ---- TriangleScene, MeshTracer ----------------------------------------------------------

TriangleScene::TriangleScene(std::span<const glm::vec3> positions, std::span<const glm::uvec3> triangles,
                             std::span<const uint32_t> materialOfTriangle, std::span<const MeshMaterial> materials)
    : impl_(std::make_unique<Impl>()) {
  if (triangles.empty()) invalid("triangles: none given");
  expectSize("materialOfTriangle", materialOfTriangle.size(), triangles.size(), true);
  Scene& s = impl_->scene;
  for (size_t i = 0; i < positions.size(); ++i)
    if (!std::isfinite(positions[i].x + positions[i].y + positions[i].z)) invalid(cat("positions[", i, "]: not finite"));
  s.positions.assign(positions.begin(), positions.end());
  s.triangles.assign(triangles.begin(), triangles.end());
  for (const MeshMaterial& m : materials) {
    Material mat;
    mat.albedo = m.albedo;
    mat.mirror = m.mirror;
    s.materials.push_back(mat);
  }
  if (s.materials.empty()) s.materials.push_back(Material{});
  for (size_t t = 0; t < triangles.size(); ++t) {
    const uint32_t m = materialOfTriangle.empty() ? 0u : materialOfTriangle[t];
    if (m >= s.materials.size()) invalid(cat("materialOfTriangle[", t, "] = ", m, ": only ", s.materials.size(), " materials"));
    s.triMaterial.push_back(m);
  }
  guarded([&] { s.finalize("triangles"); });
}
TriangleScene::TriangleScene(TriangleScene&&) noexcept = default;
TriangleScene::~TriangleScene() = default;
size_t TriangleScene::triangleCount() const { return impl_->scene.triangleCount(); }
std::span<const glm::vec3> TriangleScene::positions() const { return impl_->scene.positions; }
std::span<const glm::vec3> TriangleScene::normals() const { return impl_->scene.normals; }
std::span<const glm::uvec3> TriangleScene::triangles() const { return impl_->scene.triangles; }
std::span<const uint32_t> TriangleScene::materialOfTriangle() const { return impl_->scene.triMaterial; }
size_t TriangleScene::materialCount() const { return impl_->scene.materials.size(); }

TriangleScene::TriangleScene(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

TriangleScene TriangleScene::load(const std::string& path) {
  auto impl = std::make_unique<Impl>();
  FrameOptions o;
  o.scenePath = path;
  Frame frame;
  guarded([&] { loadFrameScene(o, frame); });  // the CLI's loading: textures on, lightmaps off
  impl->scene = std::move(frame.scene);
  return TriangleScene(std::move(impl));
}

std::vector<std::string> TriangleScene::cameraNames() const {
  std::vector<std::string> names;
  for (const CameraDesc& c : impl_->scene.cameras) names.push_back(c.name);
  return names;
}

View TriangleScene::view(const std::string& camera, int width, int height) const {
  const Scene& s = impl_->scene;
  CameraDesc desc;
  if (camera.empty()) {
    desc = s.cameras.empty() ? autoCamera(s) : s.cameras.front();
  } else {
    const auto it = std::find_if(s.cameras.begin(), s.cameras.end(), [&](const CameraDesc& c) { return c.name == camera; });
    if (it == s.cameras.end()) invalid(cat("camera \"", camera, "\": not in the scene (", cameraNames().size(), " cameras)"));
    desc = *it;
  }
  desc = guarded([&] { return withClipPlanes(desc, s); });  // the CLI's near and far planes
  View v;
  v.width = width, v.height = height;
  v.eye = desc.eye, v.target = desc.target, v.up = desc.up, v.fovY = desc.fovY;
  v.near = desc.near, v.far = desc.far;
  (void)cameraOf(v);  // the size and the pose checked as every View is
  return v;
}

glm::dvec3 TriangleScene::origin() const { return impl_->scene.origin; }

MeshTracer::MeshTracer(const TriangleScene& scene, const View& view, const std::string& name, const TracerParams& params)
    : impl_(std::make_unique<Impl>()) {
  if (name != "embree" && name != "embree-robust" && name != "grid")
    invalid(cat("tracer \"", name, "\": not a geometric tracer (use embree, embree-robust or grid)"));
  impl_->frame.scene = scene.impl().scene;
  impl_->frame.camera = cameraOf(view);
  const TracerOptions options = tracerOptions(params);
  impl_->built = guarded([&] { return buildTracer(name, impl_->frame, options); });
}
MeshTracer::MeshTracer(MeshTracer&&) noexcept = default;
MeshTracer::~MeshTracer() = default;
void MeshTracer::trace(std::span<const Ray> rays, std::span<TraceHit> hits, RaySpace space) const {
  traceIn(*impl_->built.tracer, impl_->frame.camera, Query::Closest, rays, hits, space);
}
void MeshTracer::occluded(std::span<const Ray> rays, std::span<TraceHit> hits, RaySpace space) const {
  traceIn(*impl_->built.tracer, impl_->frame.camera, Query::Any, rays, hits, space);
}

// ---- Evaluation and rendering ----------------------------------------------------------------

const char* hitClassName(HitClass c) {
  if (uint8_t(c) >= kRayClasses) invalid(cat("hitClassName: ", int(c), " is not a class"));
  return rayClassName(c);
}

std::vector<uint8_t> classifyHits(const ScreenLayers& layers, std::span<const Ray> rays, std::span<const TraceHit> hits,
                                  std::span<const TraceHit> truth) {
  expectSize("hits", hits.size(), rays.size(), false);
  expectSize("truth", truth.size(), rays.size(), false);
  const Frame& f = layers.impl().frame;
  std::vector<uint8_t> classes(rays.size());
  for (size_t i = 0; i < rays.size(); ++i)
    classes[i] = uint8_t(classifyRay(rays[i], hits[i], truth[i], Query::Closest, f.camera, f.layers));
  return classes;
}

namespace {

/// The frame `layertrace render` makes of a scene: the view's camera, its default light, and the
/// k layers captured with a z-thickness of thicknessPx pixel footprints.
Frame capturedFrame(const TriangleScene& scene, const View& view, int k, float thicknessPx) {
  if (k < 1 || k > 16) invalid(cat("k ", k, ": must be between 1 and 16"));
  Frame frame;
  frame.camera = cameraOf(view);
  frame.thicknessPerDepth = thicknessPerDepth(frame.camera, thicknessPx);
  frame.scene = scene.impl().scene;
  frame.lights = frame.scene.lights;  // the scene's, else one above the eye (as the CLI)
  if (frame.lights.empty()) frame.lights.push_back(defaultLight(frame.camera));
  FrameOptions fo;
  fo.layers = k;
  guarded([&] { rasterizeFrame(fo, frame); });
  return frame;
}

}  // namespace

ScreenLayers captureLayers(const TriangleScene& scene, const View& view, int k, float thicknessPx) {
  auto impl = std::make_unique<ScreenLayers::Impl>();
  impl->view = view;
  impl->frame = capturedFrame(scene, view, k, thicknessPx);
  impl->frame.scene = Scene{};  // the layers are what the API traces
  return ScreenLayers(std::move(impl));
}

void RgbImage::savePng(const std::string& path) const {
  if (width < 1 || height < 1 || rgb.size() != size_t(width) * size_t(height) * 3)
    invalid(cat("RgbImage ", width, "x", height, " with ", rgb.size(), " values: not width · height · 3"));
  Image image(width, height);
  image.data = rgb;
  guarded([&] { writeImage(path, image); });
}

RgbImage render(const TriangleScene& scene, const RenderRequest& r) {
  if (!isKnownTracer(r.tracer)) invalid(cat("tracer \"", r.tracer, "\": unknown (use ", tracerNames(), ")"));
  if (r.layers < 1 || r.layers > 16) invalid(cat("layers ", r.layers, ": must be between 1 and 16"));
  const TracerOptions options = tracerOptions(r.params);
  return guarded([&] {
    validateTracerOptions(options);
    EffectConfig ec;
    ec.effect = parseEffect(r.effect);
    ec.bounces = r.bounces;
    ec.aoSamples = r.aoSamples;
    ec.maxDistance = r.maxDistance;
    ec.seed = r.seed;
    if (r.warpEye) ec.warpEye = scene.impl().scene.toWorld(*r.warpEye);
    if (r.warpTarget) ec.warpTarget = scene.impl().scene.toWorld(*r.warpTarget);
    validateEffectConfig(ec);
    const Frame frame = capturedFrame(scene, r.view, r.layers, kDefaultThicknessPx);
    const BuiltTracer built = buildTracer(r.tracer, frame, options);
    ec.countRays = false;  // no counters asked for: the counter-free tracer, and its vector marches
    const EffectResult result = renderEffect(frame, *built.tracer, ec);
    RgbImage out;
    out.width = result.image.width, out.height = result.image.height;
    out.rgb = result.image.data;
    return out;
  });
}

}  // namespace lt
