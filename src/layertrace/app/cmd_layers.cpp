#include <algorithm>
#include <filesystem>
#include <iostream>

#include "layertrace/app/commands.h"
#include "layertrace/eval/verify_layers.h"
#include "layertrace/gpu/gpu_context.h"
#include "layertrace/pipeline/gpu_tracers.h"
#include "layertrace/geometry/embree_scene.h"
#include "layertrace/util/error.h"
#include "layertrace/util/image.h"

namespace lt {
namespace fs = std::filesystem;

void writeStats(const std::string& path, const std::string& json) {
  if (!path.empty()) writeFileAtomic(path, json + "\n");
}

void ensureDirectory(const std::string& dir, const std::string& option) {
  if (!createOutputDirectory(dir)) inputError(option, " ", dir, ": cannot create directory");
}

Image layerAlbedo(const LayerArrays& L, int layer) {
  Image albedo(L.width, L.height);
  for (int y = 0; y < L.height; ++y)
    for (int x = 0; x < L.width; ++x)
      if (layer < L.countAt(x, y)) albedo.set(x, y, unpackAlbedo(L.pixel(x, y)[layer].albedoSpec));
  return albedo;
}

ComplexityImages depthComplexityImages(int width, int height, const std::vector<uint32_t>& counts) {
  ComplexityImages out{Image(width, height), Image(width, height, 1)};
  for (uint32_t c : counts) out.max = std::max(out.max, c);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      const uint32_t c = counts[size_t(y) * size_t(width) + size_t(x)];
      out.heat.set(x, y, c == 0 ? glm::vec3(0.0f) : heatColor(float(c) / float(out.max)));
      out.counts.at(x, y)[0] = float(c);
    }
  return out;
}

/// Depth agreement of a GPU capture with the CPU's: both evaluate the pixel-centre ray against the
/// triangle's plane, from camera-space vertices the two devices transform with different rounding.
constexpr float kGpuCaptureTolerance = 1e-5f;

int runLayers(const LayersOptions& o) {
  const std::string outDir = o.run.output;
  FrameOptions fo = o.run.frame;
  if (o.capture != "lists" && o.capture != "peel") inputError("--capture ", o.capture, ": unknown (use lists or peel)");
  const bool peel = o.capture == "peel";
  fo.captureLists = o.verify && !peel;  // --verify compares every fragment of every list with Embree
  fo.depthPeeling = peel && o.run.device != "gpu";
  std::shared_ptr<GpuContext> gpu;
  if (o.run.device == "gpu") gpu = openGpu();  // before the scene: a machine without one is told at once
  Frame frame;
  if (gpu) {
    loadFrameScene(fo, frame);
    rasterizeFrameOnGpu(*gpu, fo, o.capture, frame);
  } else {
    frame = buildFrame(fo);
  }
  nlohmann::json stats = frameStats(frame);
  stats["tracer"] = nullptr;
  stats["effect"] = nullptr;
  stats["device"] = o.run.device;
  if (gpu) stats["gpu"] = gpuStats(*gpu), stats["gpu_renderer"] = gpu->renderer();

  if (o.verify) {
    const EmbreeScene embree(frame.scene);
    const Scene* frontFaces = fo.frontFacesOnly ? &frame.scene : nullptr;
    // Depth peeling keeps no lists: its k layers against Embree's first k surfaces.
    const VerifyResult v = peel ? verifyLayerArrays(frame.layers, frame.camera, embree, frontFaces)
                                                      : verifyLayers(frame.lists, frame.camera, embree, frontFaces);
    stats["verify"] = {{"pixels", v.pixels},
                       {"pixels_matching", v.matching},
                       {"match_fraction", v.matchFraction()},
                       {"pixels_fewer_fragments", v.fewerFragments},
                       {"pixels_more_fragments", v.moreFragments},
                       {"pixels_depth_mismatch", v.depthMismatch},
                       {"relative_depth_tolerance", kVerifyRelativeTolerance},
                       {"conditioning_epsilons", kVerifyConditioningEpsilons}};
    if (gpu) {
      // The GPU's capture against the CPU's of the same view: the same triangle in the same
      // slot, depths within kGpuCaptureTolerance. Rasterizers may break the tie of a pixel centre
      // exactly on a shared edge differently, and the GPU's transforms round differently.
      FrameOptions cpuOptions = fo;  // (the same capture method on the CPU)
      cpuOptions.captureLists = false;
      cpuOptions.depthPeeling = peel;
      const Frame cpu = buildFrame(cpuOptions);
      const LayerAgreement a = compareLayerArrays(frame.layers, cpu.layers, kGpuCaptureTolerance);
      stats["verify"]["gpu_vs_cpu"] = {{"pixel_layers", a.pixelLayers},
                                       {"matching", a.matching},
                                       {"match_fraction", a.matchFraction()},
                                       {"same_bits", a.sameBits},
                                       {"pixels_count_differ", a.countsDiffer},
                                       {"relative_depth_tolerance", kGpuCaptureTolerance}};
    }
  }

  // Images: everything is computed before the first file is written.
  const LayerArrays& L = frame.layers;
  const int W = L.width, H = L.height;
  float dmin = frame.camera.far(), dmax = frame.camera.near();
  for (size_t p = 0; p < L.count.size(); ++p)
    for (int i = 0; i < L.count[p]; ++i) {
      dmin = std::min(dmin, L.slots[p * size_t(L.k) + size_t(i)].depth);
      dmax = std::max(dmax, L.slots[p * size_t(L.k) + size_t(i)].depth);
    }
  std::vector<std::pair<std::string, Image>> images;
  for (int layer = 0; layer < L.k; ++layer) {
    Image albedo = layerAlbedo(L, layer), normal(W, H), depth(W, H, 1);
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        if (layer >= L.countAt(x, y)) continue;
        const FragmentNode& f = L.pixel(x, y)[layer];
        normal.set(x, y, decodeOctahedral(f.normal) * 0.5f + 0.5f);
        depth.at(x, y)[0] = dmax > dmin ? 1.0f - 0.9f * (f.depth - dmin) / (dmax - dmin) : 1.0f;
      }
    images.emplace_back(cat("layer", layer, "_albedo.png"), std::move(albedo));
    images.emplace_back(cat("layer", layer, "_normal.png"), std::move(normal));
    images.emplace_back(cat("layer", layer, "_depth.png"), std::move(depth));
  }
  ComplexityImages dc = depthComplexityImages(W, H, frame.lists.complexity);
  const uint32_t maxDc = dc.max;
  images.emplace_back("depth_complexity.png", std::move(dc.heat));
  images.emplace_back("depth_complexity.exr", std::move(dc.counts));

  ensureDirectory(outDir, "-o");
  for (const auto& [name, image] : images) {
    const bool data = name.find("_depth") != std::string::npos || name.find("_normal") != std::string::npos;
    writeImage((fs::path(outDir) / name).string(), image, !data);
  }
  // --pixelstats: the capture's per-pixel counter, the fragments each pixel's list held.
  if (!o.run.pixelStats.empty()) {
    ensureDirectory(o.run.pixelStats, "--pixelstats");
    writeImage((fs::path(o.run.pixelStats) / "fragments.exr").string(), images.back().second);
  }
  writeStats(o.run.statsPath, stats.dump(2));
  if (!o.run.quiet) {
    std::cout << "layers: " << frame.scene.name << " " << W << "x" << H << " k=" << L.k << ": "
              << frame.lists.generated << " fragments, depth complexity mean "
              << stats["fragments"]["depth_complexity_mean"].get<double>() << " max " << maxDc << "; raster "
              << frame.rasterMs << " ms, sort " << frame.sortMs << " ms";
    if (gpu) std::cout << " on " << gpu->renderer() << " (" << o.capture << ")";
    if (o.verify) std::cout << "; verify match " << stats["verify"]["match_fraction"].get<double>();
    if (o.verify && gpu) std::cout << ", GPU = CPU for " << stats["verify"]["gpu_vs_cpu"]["match_fraction"].get<double>() << " of pixel-layers";
    std::cout << "\n  wrote " << images.size() << " images to " << outDir << "\n";
  }
  return 0;
}

}  // namespace lt
