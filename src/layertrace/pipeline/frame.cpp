#include "layertrace/pipeline/frame.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>

#include <glm/geometric.hpp>
#include <tbb/task_arena.h>

#include "layertrace/scene/load.h"
#include "layertrace/util/error.h"
#include "layertrace/util/simd_targets.h"

namespace lt {

namespace {
double msSince(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
}
}  // namespace

void validateFrameOptions(const FrameOptions& o) {
  if (o.width <= 0) inputError("--width ", o.width, ": must be positive");
  if (o.height <= 0) inputError("--height ", o.height, ": must be positive");
  if (o.width > 32768 || o.height > 32768) inputError("--width/--height ", o.width, "x", o.height, ": at most 32768 per side");
  if (o.layers < 1 || o.layers > 16) inputError("--layers ", o.layers, ": must be between 1 and 16");
  if (o.thickness && !(*o.thickness > 0.0f && std::isfinite(*o.thickness)))
    inputError("--thickness ", *o.thickness, ": must be positive and finite");
  if (o.thicknessPx && !(*o.thicknessPx > 0.0f && *o.thicknessPx <= 1e6f))
    inputError("--thickness-px ", *o.thicknessPx, ": must be in (0, 1e6] pixel footprints");
  if (o.thickness && o.thicknessPx) inputError("--thickness-px ", *o.thicknessPx, ": give either --thickness or --thickness-px");
  if (o.fov && !(*o.fov > 0.0f && *o.fov < 180.0f)) inputError("--fov ", *o.fov, ": must be in (0, 180) degrees");
  for (const glm::dvec4& l : o.lights)
    if (!(l.w >= 0.0) || !std::isfinite(l.x + l.y + l.z + l.w)) inputError("--light ", l.x, ",", l.y, ",", l.z, ",", l.w, ": invalid");
  // Buffers per pixel: heads + counters (8), the initial pool of 8 fragments (8 × 20; the
  // tile-local capture has none), k layer slots (k × 20 + 1), and images/tracer state (~64).
  const uint64_t pixels = uint64_t(o.width) * uint64_t(o.height);
  const uint64_t pool = !needsFragmentLists(o) ? 0 : o.pool ? o.pool * 20 : pixels * 160;
  const uint64_t need = pixels * (8 + uint64_t(o.layers) * 21 + 64) + pool;
  checkAllocation(cat("--width/--height ", o.width, "x", o.height, ": the frame's buffers"), need);
}

PointLight defaultLight(const Camera& camera) {
  const CameraDesc& d = camera.desc();
  const float dist = glm::length(d.target - d.eye);
  const glm::vec3 up = glm::normalize(camera.dirToWorld({0.0f, 1.0f, 0.0f}));
  return {d.eye + up * (0.1f * dist), glm::vec3(dist * dist)};
}

void loadFrameScene(const FrameOptions& o, Frame& frame) {
  validateFrameOptions(o);
  const auto t0 = std::chrono::steady_clock::now();
  frame.scene = loadScene(o.scenePath);
  if (!o.lightmaps) dropLightmaps(frame.scene);
  if (!o.textures) flattenTextures(frame.scene);
  frame.loadMs = msSince(t0);
  CameraDesc desc;
  if (!o.cameraName.empty()) {
    bool found = false;
    std::string names;
    for (const CameraDesc& c : frame.scene.cameras) {
      names += (names.empty() ? "" : ", ") + c.name;
      if (!found && c.name == o.cameraName) desc = c, found = true;  // the first of that name: the file's own before a model's
    }
    if (!found)
      inputError("--camera ", o.cameraName, ": no such camera in ", o.scenePath,
                 names.empty() ? std::string(" (it has none)") : " (has: " + names + ")");
  } else if (!frame.scene.cameras.empty()) {
    desc = frame.scene.cameras.front();
  } else {
    desc = autoCamera(frame.scene);
  }
  const Scene& scene = frame.scene;
  // The view options are world coordinates; the scene's own are relative to its origin.
  auto text = [](glm::dvec3 v) { return cat(v.x, ",", v.y, ",", v.z); };
  auto local = [&](const char* option, const glm::dvec3& p) {
    const glm::vec3 v = scene.fromWorld(p);
    if (!std::isfinite(v.x + v.y + v.z)) inputError(option, text(p), ": out of range");
    return v;
  };
  if (o.eye) desc.eye = local("--eye ", *o.eye), desc.name = "custom";
  if (o.target) desc.target = local("--target ", *o.target), desc.name = "custom";
  if (o.up) desc.up = *o.up;
  if (o.fov) desc.fovY = *o.fov;
  // The view options' own errors name the option (the camera's checks name the camera).
  if ((o.eye || o.target) && desc.eye == desc.target)
    inputError(o.eye ? "--eye " : "--target ", text(o.eye ? *o.eye : *o.target), ": equals the ", o.eye ? "target " : "eye ",
               text(scene.toWorld(o.eye ? desc.target : desc.eye)), " (the view needs a direction)");
  if (o.up && !(glm::length(*o.up) > 0.0f)) inputError("--up ", text(*o.up), ": is the zero vector");
  if (o.fov && !(*o.fov > 0.0f && *o.fov < 180.0f)) inputError("--fov ", *o.fov, ": must be in (0, 180) degrees");
  setFrameView(o, desc, frame);
  frame.lights = frame.scene.lights;
  for (const glm::dvec4& l : o.lights) frame.lights.push_back({local("--light ", glm::dvec3(l)), glm::vec3(float(l.w))});
  if (frame.lights.empty()) frame.lights.push_back(defaultLight(frame.camera));
}

void setFrameView(const FrameOptions& o, const CameraDesc& desc, Frame& frame) {
  frame.camera = Camera(withClipPlanes(desc, frame.scene), o.width, o.height);
  frame.thickness = o.thickness ? *o.thickness : 0.0f;
  frame.thicknessPerDepth = o.thickness ? 0.0f : o.thicknessPx.value_or(kDefaultThicknessPx) / frame.camera.focal();
}

namespace {
/// Before a capture: the frame's own pyramid lets go of the old level 0 (so that level 0 is
/// reused); a pyramid a tracer of the previous frame still holds is left to that tracer.
void releasePyramid(Frame& frame) {
  if (frame.pyramid && frame.pyramid.use_count() == 1) frame.pyramid->base.reset();
  else frame.pyramid.reset();
}
/// The frame's pyramid to build into (its memory reused from frame to frame), made if none.
IntervalPyramid& ownPyramid(Frame& frame) {
  if (!frame.pyramid) frame.pyramid = std::make_shared<IntervalPyramid>();
  return *frame.pyramid;
}
/// FrameOptions::pyramid built after the capture over the frame's level 0, or none.
void finishPyramid(const FrameOptions& o, Frame& frame) {
  if (!o.pyramid) {
    frame.pyramid.reset();
    return;
  }
  buildIntervalPyramid(frame.intervals, frame.camera, *o.pyramid, ownPyramid(frame));
  frame.pyramidConfig = *o.pyramid;
}
}  // namespace

bool needsFragmentLists(const FrameOptions& o) {
  return o.captureLists || o.referenceCapture || o.pool != 0 || o.adaptiveThickness || o.minSeparation > 0.0f;
}

LayerConfig layerConfig(const FrameOptions& o, const Frame& frame) {
  LayerConfig lc;
  lc.k = o.layers;
  lc.thickness = frame.thickness;
  lc.thicknessPerDepth = frame.thicknessPerDepth;
  lc.minSeparation = o.minSeparation;
  lc.adaptiveThickness = o.adaptiveThickness;
  return lc;
}

void rasterizeFrame(const FrameOptions& o, Frame& frame) {
  RasterConfig rc;
  rc.poolCapacity = o.pool;
  rc.growOnOverflow = o.pool == 0;
  rc.frontFacesOnly = frame.frontFacesOnly = o.frontFacesOnly;
  const LayerConfig lc = layerConfig(o, frame);
  frame.geometryPasses = 1;
  if (o.depthPeeling) {
    if (o.pool != 0 || o.referenceCapture || o.captureLists) inputError("--capture peel: keeps no fragment lists (drop --pool)");
    CaptureStats cs;
    FragmentLists& lists = frame.lists;
    lists.head = {}, lists.nodes = {}, lists.triangle = {};
    releasePyramid(frame);
    frame.capture.capturePeeled(frame.scene, frame.camera, rc, lc, frame.layers, lists.complexity, &cs);
    lists.width = frame.camera.width(), lists.height = frame.camera.height();
    uint64_t fragments = 0;
    for (uint32_t c : lists.complexity) fragments += c;
    lists.generated = lists.stored = fragments;  // the scene's fragments (one pass)
    frame.fragmentsRasterized = cs.generated;
    frame.geometryPasses = lc.k;
    frame.raster = RasterStats{cs.ms(), 0, 1, cs.subTriangles};
    frame.rasterMs = cs.ms();
    frame.sortMs = 0.0;
    frame.capturePipeline = "peel";
    if (!frame.intervals || frame.intervals.use_count() > 1) frame.intervals = std::make_shared<IntervalLayers>();
    makeIntervalLayers(frame.layers, frame.layers.k, *frame.intervals);
    finishPyramid(o, frame);
    return;
  }
  if (o.pool == 0 && !o.referenceCapture) {
    // Tile-local capture: the k layers straight from the rasterizer, and the lists
    // too when something reads them (exact-size storage from a counting pass).
    CaptureStats cs;
    FragmentLists& lists = frame.lists;
    // Level 0 of the interval pyramid, written from each finished tile (reused unless a
    // pyramid of the previous frame still holds it).
    validateLayerConfig(lc);  // before anything is sized by k
    releasePyramid(frame);
    if (!frame.intervals || frame.intervals.use_count() > 1) frame.intervals = std::make_shared<IntervalLayers>();
    IntervalLayers& level0 = *frame.intervals;
    sizeIntervalLayers(frame.camera.width(), frame.camera.height(), lc.k, level0);
    // Levels 1… per tile too when asked, unless a whole-list rule rewrites the layers after
    // the pass (then, as by default, they are built after it: finishPyramid).
    const bool tilePyramid = o.pyramid && o.pyramidPerTile && !lc.adaptiveThickness && !(lc.minSeparation > 0.0f);
    if (tilePyramid) frame.pyramidTiles.begin(frame.intervals, frame.camera, *o.pyramid, rc.tileSize, ownPyramid(frame));
    const TileDone writeLevel0 = [&](int x0, int y0, int x1, int y1) {
      writeIntervals(frame.layers, x0, y0, x1, y1, level0);
      if (tilePyramid) frame.pyramidTiles.tile(x0, y0, x1, y1);
    };
    if (!needsFragmentLists(o)) {
      lists.head = {}, lists.nodes = {}, lists.triangle = {};
      frame.capture.capture(frame.scene, frame.camera, rc, lc, frame.layers, lists.complexity, &cs, &writeLevel0);
      lists.width = frame.camera.width(), lists.height = frame.camera.height();
      lists.generated = lists.stored = cs.generated;
      frame.sortMs = 0.0;
      frame.capturePipeline = "tiles";
    } else {
      LayerConfig plain = lc;  // the whole-list rules sort the lists afterwards
      plain.adaptiveThickness = false, plain.minSeparation = 0.0f;
      frame.capture.captureWithLists(frame.scene, frame.camera, rc, plain, frame.layers, lists, &cs, &writeLevel0);
      const auto t0 = std::chrono::steady_clock::now();
      if (lc.adaptiveThickness || lc.minSeparation > 0.0f) {
        frame.layers = sortAndTruncate(lists, lc);
        makeIntervalLayers(frame.layers, frame.layers.k, level0);
      }
      frame.sortMs = msSince(t0);
      frame.capturePipeline = "tiles+lists";
    }
    frame.raster = RasterStats{cs.ms(), 0, 1, cs.subTriangles};
    frame.rasterMs = cs.ms();  // rasterize and sort to k are one pass: the sort is inside
    if (tilePyramid) {
      // The pyramid's time (its tiles' merges over the threads, and the layout in cell order)
      // is reported as the hierarchy's (IntervalPyramid::buildMs), not as raster time.
      frame.pyramidTiles.finish(tbb::this_task_arena::max_concurrency());
      frame.rasterMs = std::max(0.0, frame.rasterMs - (frame.pyramid->buildMs - frame.pyramidTiles.finishMs()));
      frame.pyramidConfig = *o.pyramid;
    } else {
      finishPyramid(o, frame);
    }
    return;
  }
  // The reference pipeline: a pool (fixed by --pool N, overflow counted exactly; or 8 fragments
  // per pixel, grown once when it overflows), then sortAndTruncate.
  frame.capturePipeline = "reference";
  releasePyramid(frame);
  frame.lists = rasterize(frame.scene, frame.camera, rc, &frame.raster);
  frame.rasterMs = frame.raster.ms;
  if (frame.lists.lost() > 0)
    inputError("--pool ", o.pool, ": fragment pool overflow: ", frame.lists.generated, " fragments generated, ",
               frame.lists.stored, " stored, ", frame.lists.lost(), " lost (use --pool ", frame.lists.generated,
               " or more, or 0 for automatic)");
  const auto t0 = std::chrono::steady_clock::now();
  frame.layers = sortAndTruncate(frame.lists, lc);
  frame.intervals = std::make_shared<IntervalLayers>(makeIntervalLayers(frame.layers, frame.layers.k));
  frame.sortMs = msSince(t0);
  finishPyramid(o, frame);
}

Frame buildFrame(const FrameOptions& o) {
  Frame frame;
  loadFrameScene(o, frame);
  rasterizeFrame(o, frame);
  return frame;
}

nlohmann::json worldStats(const Scene& scene, glm::vec3 p) {
  if (scene.origin == glm::dvec3(0.0)) return nlohmann::json::array({p.x, p.y, p.z});  // floats print shorter
  const glm::dvec3 w = scene.toWorld(p);
  return nlohmann::json::array({w.x, w.y, w.z});
}

nlohmann::json frameStats(const Frame& f) {
  nlohmann::json j;
  j["scene"] = f.scene.name;
  j["machine"] = machineName();  // the CPU, its threads and vector target: what a time depends on
  j["width"] = f.camera.width();
  j["height"] = f.camera.height();
  j["layers"] = f.layers.k;
  j["camera"] = f.camera.desc().name;
  // The thickness at the view's target depth, and how it is set.
  const CameraDesc& view = f.camera.desc();
  j["thickness"] = f.thickness + f.thicknessPerDepth * glm::length(view.target - view.eye);
  j["front_faces_only"] = f.frontFacesOnly;
  if (f.thicknessPerDepth > 0.0f) j["thickness_px"] = f.thicknessPerDepth * f.camera.focal();
  else j["thickness_fixed"] = f.thickness;
  j["triangles"] = f.scene.triangleCount();
  auto world = [&](glm::vec3 p) { return worldStats(f.scene, p); };
  const Bounds b = f.scene.bounds();
  j["bounds"] = {world(b.lo), world(b.hi)};
  const CameraDesc& cd = f.camera.desc();
  j["view"] = {{"eye", world(cd.eye)}, {"target", world(cd.target)},
               {"up", {cd.up.x, cd.up.y, cd.up.z}}, {"fov", cd.fovY}, {"near", f.camera.near()}, {"far", f.camera.far()}};
  j["timings_ms"]["load"] = f.loadMs;
  j["timings_ms"]["raster"] = f.rasterMs;
  j["timings_ms"]["sort"] = f.sortMs;
  // "tiles": rasterized and sorted to k in one tile-local pass (raster includes the sort);
  // "tiles+lists": the same pass also wrote every fragment to exact-size per-pixel lists;
  // "reference": lists in a pool (--pool), then sorted (Hofmann et al. 2017, §4.1–4.2);
  // "peel": depth peeling, k geometry passes; "gpu-lists", "gpu-peel": the same on the GPU.
  j["capture_pipeline"] = f.capturePipeline;
  const size_t pixelCount = size_t(f.camera.width()) * size_t(f.camera.height());
  uint64_t maxDc = 0;
  if (f.deviceCapture) {
    // Where the layers live on the device: the same sizes as read back (the complexity per
    // pixel, the k-layer arrays).
    j["memory_bytes"]["lists"] = pixelCount * sizeof(uint32_t);
    j["memory_bytes"]["arrays"] = pixelCount * (size_t(f.layers.k) * (sizeof(FragmentNode) + sizeof(uint32_t)) + 1);
    maxDc = f.deviceCapture->maxComplexity;
  } else {
    j["memory_bytes"]["lists"] = f.lists.memoryBytes();
    j["memory_bytes"]["arrays"] = f.layers.memoryBytes();
    for (uint32_t c : f.lists.complexity) maxDc = std::max<uint64_t>(maxDc, c);
  }
  const double pixels = f.deviceCapture ? double(pixelCount) : double(f.lists.complexity.size());
  j["fragments"]["total"] = f.lists.generated;
  j["fragments"]["stored"] = f.lists.stored;
  j["fragments"]["depth_complexity_mean"] = pixels > 0 ? double(f.lists.generated) / pixels : 0.0;
  j["fragments"]["depth_complexity_max"] = maxDc;
  j["fragments"]["overflow"] = f.lists.lost();
  j["fragments"]["overflow_first_pass"] = f.raster.overflowLost;
  j["fragments"]["raster_passes"] = f.raster.passes;
  j["fragments"]["pool_capacity"] = f.lists.capacity();
  if (f.capturePipeline.rfind("gpu-", 0) == 0) j["memory_bytes"]["gpu_capture"] = f.gpuMemoryBytes;
  if (f.capturePipeline.rfind("gpu-", 0) == 0 || f.capturePipeline == "peel") j["fragments"]["geometry_passes"] = f.geometryPasses;
  if (f.capturePipeline == "peel") j["fragments"]["rasterized"] = f.fragmentsRasterized;  // over the k passes
  return j;
}

}  // namespace lt
