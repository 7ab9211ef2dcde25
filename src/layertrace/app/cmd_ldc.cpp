// `layertrace ldc`: what the layered depth cube (Bürger et al. 2007) captured, per axis.
#include <algorithm>
#include <filesystem>
#include <iostream>

#include "layertrace/util/simd_targets.h"
#include "layertrace/app/commands.h"
#include "layertrace/util/error.h"
#include "layertrace/util/image.h"

namespace lt {
namespace fs = std::filesystem;

int runLdc(const LdcOptions& o) {
  validateLdcConfig(o.tracers.ldc);
  const std::string outDir = o.run.output;
  Frame frame;
  loadFrameScene(o.run.frame, frame);
  const LayeredDepthCube ldc = buildLdc(frame.scene, o.tracers.ldc);
  nlohmann::json stats = {{"scene", frame.scene.name}, {"machine", machineName()}, {"triangles", frame.scene.triangleCount()}, {"threads", o.run.threads}};
  stats["ldc"] = ldcStats(ldc, nullptr);

  // Images: everything is computed before the first file is written. Image rows follow the
  // view's screen (y down); each view's header in ldc.h says which world axes they are.
  std::vector<std::pair<std::string, Image>> images;
  for (const LdcView& v : ldc.views) {
    const std::string axis(1, "xyz"[v.axis]);
    std::vector<uint32_t> counts(size_t(v.width) * size_t(v.height));
    for (size_t p = 0; p < counts.size(); ++p) counts[p] = v.offset[p + 1] - v.offset[p];
    ComplexityImages dc = depthComplexityImages(v.width, v.height, counts);
    Image albedo(v.width, v.height);
    for (int y = 0; y < v.height; ++y)
      for (int x = 0; x < v.width; ++x)
        if (v.countAt(x, y)) albedo.set(x, y, unpackAlbedo(v.samples[v.offset[v.texelIndex(x, y)]].albedoSpec));
    const uint32_t maxDc = dc.max;
    images.emplace_back("ldc_" + axis + "_depth_complexity.png", std::move(dc.heat));
    images.emplace_back("ldc_" + axis + "_depth_complexity.exr", std::move(dc.counts));
    images.emplace_back("ldc_" + axis + "_albedo.png", std::move(albedo));
    stats["ldc"]["views"][axis]["depth_complexity_max"] = maxDc;
  }
  ensureDirectory(outDir, "-o");
  for (const auto& [name, image] : images) writeImage((fs::path(outDir) / name).string(), image);
  writeStats(o.run.statsPath, stats.dump(2));
  if (!o.run.quiet) {
    std::cout << "ldc: " << frame.scene.name << " " << ldc.config.resolution << " texels along the longest axis (texel "
              << ldc.texel << "): " << ldc.samples() << " samples, " << ldc.memoryBytes() / (1024.0 * 1024.0) << " MiB, "
              << ldc.lostTriangles() << " triangles covering no texel centre (centroid samples), built in " << ldc.buildMs
              << " ms\n  wrote " << images.size() << " images to " << outDir << "\n";
  }
  return 0;
}

}  // namespace lt
