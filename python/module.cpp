// The Python package's native part, `layertrace._layertrace` (docs/python.md). The Python side
// (python/layertrace/__init__.py) turns keyword arguments into the CLI's options and calls the
// functions here; this file parses them with the CLI's own parser (app/cli.h parseCli), so a
// parameter, a preset, a default or an error message means the same in both.
//
// Layer: a front end beside apps/: it may include every layer of the library.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cmath>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <tbb/global_control.h>

#include "layertrace/app/cli.h"
#include "layertrace/app/commands.h"
#include "layertrace/hssr/interval_pyramid.h"
#include "layertrace/pipeline/frame.h"
#include "layertrace/pipeline/gpu_tracers.h"
#include "layertrace/pipeline/tracer_registry.h"
#include "layertrace/raster/fragment.h"
#include "layertrace/util/error.h"
#include "layertrace/util/parallel.h"

namespace py = pybind11;

namespace {

using lt::CliCommand;

/// The CLI's parse of `layertrace ARGS…` (render or compare).
CliCommand parse(const std::vector<std::string>& args) {
  std::vector<const char*> argv{"layertrace"};
  for (const std::string& a : args) argv.push_back(a.c_str());
  return lt::parseCli(int(argv.size()), argv.data());
}

/// --threads N for the duration of one call (0: every core), as the CLI applies it.
std::optional<tbb::global_control> threadLimit(int threads) {
  if (threads < 0) throw lt::InputError(lt::cat("threads ", threads, ": must be 0 (every core) or more"));
  if (threads == 0) return std::nullopt;
  return std::optional<tbb::global_control>(std::in_place, tbb::global_control::max_allowed_parallelism, size_t(threads));
}

/// Runs `work` without the GIL under the thread limit of `threads` (C++ work that may take long).
template <class F>
auto withoutGil(int threads, F&& work) {
  py::gil_scoped_release free;
  const auto limit = threadLimit(threads);
  return work();
}

/// A numpy array over `owner`'s memory: no copy, and the array keeps `owner` alive.
template <class T, class Owner>
py::array_t<T> view(std::shared_ptr<Owner> owner, const T* data, std::vector<py::ssize_t> shape) {
  auto* keep = new std::shared_ptr<Owner>(std::move(owner));
  py::capsule base(keep, [](void* p) { delete static_cast<std::shared_ptr<Owner>*>(p); });
  return py::array_t<T>(shape, data, base);
}

/// An image as an (H, W, C) float32 array that owns the pixels (moved, not copied).
py::array_t<float> imageArray(lt::Image image) {
  auto owned = std::make_shared<lt::Image>(std::move(image));
  const lt::Image& i = *owned;
  return view<float>(owned, i.data.data(), {i.height, i.width, i.channels});
}

py::dict cameraDict(const lt::Scene& scene, const lt::CameraDesc& c) {
  auto world = [&](glm::vec3 p) {
    const glm::dvec3 w = scene.toWorld(p);
    return py::make_tuple(w.x, w.y, w.z);
  };
  py::dict d;
  d["name"] = c.name;
  d["eye"] = world(c.eye);
  d["target"] = world(c.target);
  d["up"] = py::make_tuple(c.up.x, c.up.y, c.up.z);
  d["fov"] = c.fovY;
  return d;
}

/// A scene's description: its cameras and the one the CLI takes by default.
py::dict loadScene(const std::string& path) {
  lt::FrameOptions o;
  o.scenePath = path;
  lt::Frame frame;
  {
    py::gil_scoped_release free;
    lt::loadFrameScene(o, frame);
  }
  py::list cameras;
  for (const lt::CameraDesc& c : frame.scene.cameras) cameras.append(cameraDict(frame.scene, c));
  py::dict d;
  d["name"] = frame.scene.name;
  d["cameras"] = cameras;
  d["default_camera"] = cameraDict(frame.scene, frame.camera.desc());
  d["triangles"] = frame.scene.triangleCount();
  return d;
}

/// A captured frame: its k layers, and the tracers built over them on demand.
class Layers {
 public:
  Layers(const std::vector<std::string>& args, const std::string& device, int threads) {
    const CliCommand c = parse(args);
    lt::FrameOptions fo = c.render.run.frame;
    py::gil_scoped_release free;
    const auto limit = threadLimit(threads);
    frame_ = std::make_shared<lt::Frame>();
    if (device == "gpu") {
      const std::shared_ptr<lt::GpuContext> gpu = lt::openGpu();
      lt::loadFrameScene(fo, *frame_);
      lt::rasterizeFrameOnGpu(*gpu, fo, fo.depthPeeling ? "peel" : "lists", *frame_);
    } else if (device == "cpu") {
      *frame_ = lt::buildFrame(fo);
    } else {
      throw lt::InputError(lt::cat("--device ", device, ": unknown (use cpu or gpu)"));
    }
    const lt::LayerArrays& L = frame_->layers;
    const size_t slots = L.slots.size();
    arrays_ = std::make_shared<Arrays>();
    arrays_->depth.resize(slots);
    arrays_->back.resize(slots);
    arrays_->normal.resize(slots * 3);
    arrays_->triangle.resize(slots);
    lt::parallelFor(size_t(0), slots, [&](size_t i) {
      const lt::FragmentNode& n = L.slots[i];
      const bool stored = int(i % size_t(L.k)) < int(L.count[i / size_t(L.k)]);
      arrays_->triangle[i] = stored ? int64_t(L.triangle[i]) : -1;
      const float nan = std::nanf("");
      arrays_->depth[i] = stored ? n.depth : nan;
      arrays_->back[i] = stored ? n.back() : nan;
      const glm::vec3 v = stored ? lt::decodeOctahedral(n.normal) : glm::vec3(nan);
      arrays_->normal[3 * i] = v.x, arrays_->normal[3 * i + 1] = v.y, arrays_->normal[3 * i + 2] = v.z;
    });
  }

  int width() const { return frame_->layers.width; }
  int height() const { return frame_->layers.height; }
  int k() const { return frame_->layers.k; }
  py::array_t<float> depth() const { return view<float>(arrays_, arrays_->depth.data(), {height(), width(), k()}); }
  py::array_t<float> back() const { return view<float>(arrays_, arrays_->back.data(), {height(), width(), k()}); }
  py::array_t<float> normal() const { return view<float>(arrays_, arrays_->normal.data(), {height(), width(), k(), 3}); }
  py::array_t<int64_t> triangle() const { return view<int64_t>(arrays_, arrays_->triangle.data(), {height(), width(), k()}); }
  py::array_t<uint8_t> count() const { return view<uint8_t>(frame_, frame_->layers.count.data(), {height(), width()}); }

  /// The interval pyramid of the tracer options given (τ, levels): per level its size and CSR
  /// lists (level 0: k intervals per pixel, +∞ past its count).
  py::list pyramid(const std::vector<std::string>& args) const {
    const CliCommand c = parse(args);
    std::shared_ptr<lt::IntervalPyramid> p;
    {
      py::gil_scoped_release free;
      p = std::make_shared<lt::IntervalPyramid>(lt::buildIntervalPyramid(frame_->layers, frame_->camera, c.render.tracers.pyramid));
    }
    py::list levels;
    for (int L = 0; L < p->levelCount(); ++L) {
      py::dict d;
      const lt::PyramidLevel& level = p->levels[size_t(L)];
      d["width"] = level.width;
      d["height"] = level.height;
      if (L == 0) {
        d["intervals"] = view<float>(p, reinterpret_cast<const float*>(p->base->slots.data()), {height(), width(), k(), 2});
      } else {
        d["offset"] = view<uint32_t>(p, level.offset.data(), {py::ssize_t(level.offset.size())});
        d["intervals"] = view<float>(p, reinterpret_cast<const float*>(level.intervals.data()), {py::ssize_t(level.intervals.size()), 2});
      }
      levels.append(d);
    }
    return levels;
  }

  /// Traces world-space rays (scene file coordinates) with the tracer of `args`.
  py::dict trace(py::array_t<float, py::array::c_style | py::array::forcecast> origins,
                 py::array_t<float, py::array::c_style | py::array::forcecast> directions, const std::string& tracer,
                 const std::vector<std::string>& args, bool fromSurface, float maxDistance, int threads) const {
    auto rows = [](const py::array_t<float, py::array::c_style | py::array::forcecast>& a, const char* name) {
      if (a.ndim() != 2 || a.shape(1) != 3)
        throw lt::InputError(lt::cat(name, ": must have shape (N, 3), not ", a.ndim() == 2 ? lt::cat("(", a.shape(0), ", ", a.shape(1), ")") : lt::cat(a.ndim(), " dimensions")));
      return size_t(a.shape(0));
    };
    const size_t n = rows(origins, "origins");
    if (rows(directions, "directions") != n)
      throw lt::InputError(lt::cat("directions: ", directions.shape(0), " rows for ", n, " origins"));
    if (!(maxDistance >= 0.0f) || !std::isfinite(maxDistance))
      throw lt::InputError(lt::cat("max_distance ", maxDistance, ": must be finite and ≥ 0 (0: the scene's diagonal)"));
    const CliCommand c = parse(args);
    const float* o = origins.data();
    const float* d = directions.data();
    std::vector<uint8_t> hit(n);
    std::vector<float> t(n), pixel(2 * n);
    std::vector<int32_t> px(2 * n), layer(n);
    std::vector<int64_t> triangle(n);
    std::vector<uint32_t> iterations(n);
    {
      py::gil_scoped_release free;
      const auto limit = threadLimit(threads);
      const lt::BuiltTracer built = lt::buildTracer(tracer, *frame_, c.render.tracers);
      const lt::Camera& cam = frame_->camera;
      const lt::Scene& scene = frame_->scene;
      if (maxDistance == 0.0f) maxDistance = scene.bounds().diagonal();  // the effects' default ray length
      for (size_t i = 0; i < n; ++i) {
        const glm::vec3 dir(d[3 * i], d[3 * i + 1], d[3 * i + 2]);
        if (!(glm::length(dir) > 0.0f) || !std::isfinite(dir.x + dir.y + dir.z))
          throw lt::InputError(lt::cat("directions[", i, "]: must be a finite, non-zero vector"));
        if (!std::isfinite(o[3 * i] + o[3 * i + 1] + o[3 * i + 2])) throw lt::InputError(lt::cat("origins[", i, "]: must be finite"));
      }
      constexpr size_t kChunk = 1024;
      lt::parallelFor(size_t(0), (n + kChunk - 1) / kChunk, [&](size_t chunk) {
        const size_t first = chunk * kChunk, count = std::min(kChunk, n - first);
        std::vector<lt::Ray> rays(count);
        std::vector<lt::TraceHit> hits(count);
        std::vector<lt::RayCounters> counters(count);
        for (size_t j = 0; j < count; ++j) {
          const size_t i = first + j;
          lt::Ray& r = rays[j];
          r.origin = cam.toCamera(scene.fromWorld(glm::dvec3(o[3 * i], o[3 * i + 1], o[3 * i + 2])));
          r.dir = glm::normalize(cam.dirToCamera(glm::normalize(glm::vec3(d[3 * i], d[3 * i + 1], d[3 * i + 2]))));
          r.maxDistance = maxDistance;
          r.startsOnSurface = fromSurface;
        }
        built.tracer->traceBatch(rays, hits, counters);
        for (size_t j = 0; j < count; ++j) {
          const size_t i = first + j;
          const lt::TraceHit& h = hits[j];
          hit[i] = h.hit;
          t[i] = h.hit ? glm::length(h.point - rays[j].origin) : std::numeric_limits<float>::infinity();
          px[2 * i] = h.hit ? h.x : -1, px[2 * i + 1] = h.hit ? h.y : -1;
          layer[i] = h.hit ? h.layer : -1;
          triangle[i] = h.hit && h.triangle != lt::kNoTriangle ? int64_t(h.triangle) : -1;
          iterations[i] = counters[j].iterations;
        }
      });
    }
    py::dict out;
    out["hit"] = py::array_t<bool>(py::ssize_t(n), reinterpret_cast<const bool*>(hit.data()));
    out["t"] = py::array_t<float>(py::ssize_t(n), t.data());
    out["pixel"] = py::array_t<int32_t>({py::ssize_t(n), py::ssize_t(2)}, px.data());
    out["layer"] = py::array_t<int32_t>(py::ssize_t(n), layer.data());
    out["triangle"] = py::array_t<int64_t>(py::ssize_t(n), triangle.data());
    out["iterations"] = py::array_t<uint32_t>(py::ssize_t(n), iterations.data());
    return out;
  }

  /// The camera of the capture (for generating rays in Python).
  py::dict camera() const { return cameraDict(frame_->scene, frame_->camera.desc()); }

 private:
  struct Arrays {
    std::vector<float> depth, back, normal;
    std::vector<int64_t> triangle;
  };
  std::shared_ptr<lt::Frame> frame_;
  std::shared_ptr<Arrays> arrays_;
};

py::tuple render(const std::vector<std::string>& args, int threads) {
  const CliCommand c = parse(args);
  lt::RenderOutput out = withoutGil(threads, [&] { return lt::renderFrame(c.render); });
  return py::make_tuple(imageArray(std::move(out.result.image)), out.stats.dump());
}

/// compare.json, and compare's images by name without ".png" ("hssr", "hssr_classes", …).
py::tuple compare(const std::vector<std::string>& args, int threads) {
  const CliCommand c = parse(args);
  lt::CompareOutput out = withoutGil(threads, [&] { return lt::compareFrame(c.compare); });
  py::dict images;
  for (auto& [name, image] : out.images) images[py::str(name.substr(0, name.size() - 4))] = imageArray(std::move(image));
  return py::make_tuple(out.stats.dump(), images);
}

}  // namespace

PYBIND11_MODULE(_layertrace, m) {
  m.doc() = "layertrace's native part; use the layertrace package (docs/python.md)";
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const lt::InputError& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    } catch (const lt::InternalError& e) {
      PyErr_SetString(PyExc_RuntimeError, e.what());
    }
  });
  m.def("load_scene", &loadScene, py::arg("path"));
  m.def("render", &render, py::arg("args"), py::arg("threads") = 0);
  m.def("compare", &compare, py::arg("args"), py::arg("threads") = 0);
  m.def("tracer_params", [] {
    std::vector<std::string> flags;
    for (const lt::TracerParam& p : lt::tracerParams()) flags.emplace_back(p.flag);
    return flags;
  });
  m.def("tracer_names", [] { return lt::tracerNames(); });
  py::class_<Layers>(m, "Layers")
      .def(py::init<const std::vector<std::string>&, const std::string&, int>(), py::arg("args"), py::arg("device") = "cpu",
           py::arg("threads") = 0)
      .def_property_readonly("width", &Layers::width)
      .def_property_readonly("height", &Layers::height)
      .def_property_readonly("k", &Layers::k)
      .def_property_readonly("depth", &Layers::depth)
      .def_property_readonly("back", &Layers::back)
      .def_property_readonly("normal", &Layers::normal)
      .def_property_readonly("triangle", &Layers::triangle)
      .def_property_readonly("count", &Layers::count)
      .def_property_readonly("camera", &Layers::camera)
      .def("pyramid", &Layers::pyramid, py::arg("args"))
      .def("trace", &Layers::trace, py::arg("origins"), py::arg("directions"), py::arg("tracer"), py::arg("args"),
           py::arg("from_surface"), py::arg("max_distance"), py::arg("threads") = 0);
}
