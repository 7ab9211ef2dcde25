// `layertrace geobench SCENE`: the irregular grid (Pérard-Gayot et al. 2017) against Embree on the same rays —
// primary rays through every pixel, AO rays (any hit, 5 % of the scene diagonal, cosine
// distributed) and diffuse bounce rays (closest hit) from the primary hits: build time, memory,
// MRays/s (median of --repeat) and agreement with Embree. --sweep adds the λ1 × λ2 table.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <random>
#include <sstream>

#include <glm/geometric.hpp>
#include <glm/gtc/constants.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "layertrace/util/parallel.h"
#include "layertrace/app/commands.h"
#include "layertrace/pipeline/gpu_tracers.h"
#include "layertrace/util/error.h"
#include "layertrace/util/timing.h"

namespace lt {
namespace fs = std::filesystem;

namespace {

struct RaySet {
  std::vector<glm::vec3> o, d;
  float tnear = 0.0f, tfar = 1e30f;
  bool anyHit = false;
};

/// Traces `rays` with `query` in parallel; returns per-ray answers (t or -1; any-hit: 1/0).
template <typename Q>
std::vector<float> traceAll(const RaySet& rays, Q&& query) {
  std::vector<float> out(rays.o.size());
  parallelFor(tbb::blocked_range<size_t>(0, rays.o.size(), 1024), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i) out[i] = query(rays.o[i], rays.d[i], rays.tnear, rays.tfar);
  });
  return out;
}

/// The grid's batch queries (several rays in flight per thread) on `rays`, answers as traceAll's.
std::vector<float> traceAllGrid(const RaySet& rays, const IrregularGrid& grid) {
  std::vector<float> out(rays.o.size());
  parallelFor(tbb::blocked_range<size_t>(0, rays.o.size(), 1024), [&](const tbb::blocked_range<size_t>& r) {
    std::vector<IrregularGrid::Query> q;
    for (size_t i = r.begin(); i != r.end(); ++i) q.push_back({rays.o[i], rays.d[i], rays.tnear, rays.tfar});
    if (rays.anyHit) {
      std::vector<uint8_t> hit(q.size());
      grid.occluded(q, hit);
      for (size_t i = 0; i < q.size(); ++i) out[r.begin() + i] = hit[i] ? 1.0f : 0.0f;
    } else {
      std::vector<GeoHit> hit(q.size());
      grid.intersect(q, hit);
      for (size_t i = 0; i < q.size(); ++i) out[r.begin() + i] = hit[i].hit() ? hit[i].t : -1.0f;
    }
  });
  return out;
}

}  // namespace

int runGeobench(const GeobenchOptions& o) {
  if (o.repeat < 1 || o.repeat > 100) inputError("--repeat ", o.repeat, ": must be between 1 and 100");
  TracerOptions to;
  to.grid = o.tracers.grid;
  validateTracerOptions(to);
  Frame frame;
  loadFrameScene(o.run.frame, frame);
  const Scene& scene = frame.scene;
  const Camera& cam = frame.camera;
  const float diag = scene.bounds().diagonal();

  // The fast baseline: default scene flags (no robust mode, no filter), HIGH build quality.
  EmbreeScene embree(scene, EmbreeScene::Mode::Fast);
  const double embreeBuild = medianMs(o.repeat, [&] { EmbreeScene e(scene, EmbreeScene::Mode::Fast); });
  IrregularGrid grid(scene, o.tracers.grid);
  const double gridBuild = medianMs(o.repeat, [&] { IrregularGrid g(scene, o.tracers.grid); });

  // The rays: primary through pixel centres; AO and diffuse from Embree's primary hits.
  RaySet primary, ao, diffuse;
  for (int y = 0; y < cam.height(); ++y)
    for (int x = 0; x < cam.width(); ++x) {
      primary.o.push_back(cam.desc().eye);
      primary.d.push_back(glm::normalize(cam.dirToWorld(cam.rayThrough({x + 0.5f, y + 0.5f}))));
    }
  const float eps = 1e-4f * diag;
  ao.tnear = diffuse.tnear = eps;
  ao.tfar = 0.05f * diag;
  ao.anyHit = true;
  std::mt19937_64 rng(o.run.seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (size_t i = 0; i < primary.o.size(); ++i) {
    const GeoHit h = embree.intersect(primary.o[i], primary.d[i], 0.0f, 1e30f);
    if (!h.hit()) continue;
    const glm::vec3 p = primary.o[i] + primary.d[i] * h.t;
    glm::vec3 n = glm::normalize(h.ng);
    if (glm::dot(n, primary.d[i]) > 0.0f) n = -n;
    const glm::vec3 t = glm::normalize(std::abs(n.x) > 0.5f ? glm::cross(n, {0, 1, 0}) : glm::cross(n, {1, 0, 0})), b = glm::cross(n, t);
    for (RaySet* set : {&ao, &diffuse}) {
      const float r1 = u(rng), r2 = u(rng), r = std::sqrt(r1), phi = 2.0f * glm::pi<float>() * r2;
      set->o.push_back(p);
      set->d.push_back(glm::normalize(t * (r * std::cos(phi)) + b * (r * std::sin(phi)) + n * std::sqrt(std::max(0.0f, 1.0f - r1))));
    }
  }

  auto embreeQ = [&](const RaySet& s) {
    return [&](glm::vec3 a, glm::vec3 d, float tn, float tf) {
      if (s.anyHit) return embree.occluded(a, d, tn, tf) ? 1.0f : 0.0f;
      const GeoHit h = embree.intersect(a, d, tn, tf);
      return h.hit() ? h.t : -1.0f;
    };
  };
  auto gridQ = [&](const IrregularGrid& g, const RaySet& s) {
    return [&g, &s](glm::vec3 a, glm::vec3 d, float tn, float tf) {
      if (s.anyHit) return g.occluded(a, d, tn, tf) ? 1.0f : 0.0f;
      const GeoHit h = g.intersect(a, d, tn, tf);
      return h.hit() ? h.t : -1.0f;
    };
  };
  // Agreement: the same answer (any hit), or the same distance within 1e-4 relative (closest:
  // two triangles sharing the edge a ray passes through have the same t).
  auto same = [](float a, float b) {
    return (a < 0.0f && b < 0.0f) || (a >= 0.0f && b >= 0.0f && std::abs(a - b) <= 1e-4f * std::max(a, b) + 1e-6f);
  };
  auto agreement = [&](const std::vector<float>& a, const std::vector<float>& b) {
    size_t n = 0;
    for (size_t i = 0; i < a.size(); ++i) n += same(a[i], b[i]);
    return a.empty() ? 1.0 : double(n) / double(a.size());
  };
  // Plain Embree is not watertight: a ray through the edge two triangles share can pass between
  // them, where the grid's watertight test finds the nearer one. Where the two differ, robust
  // Embree (watertight) decides; agreement_robust_* counts those rays as agreeing when the grid
  // answers as robust Embree does.
  std::unique_ptr<EmbreeScene> robust;
  auto robustAgreement = [&](const RaySet& set, const std::vector<float>& plain, const std::vector<float>& answers) {
    size_t n = 0;
    for (size_t i = 0; i < plain.size(); ++i) {
      if (same(plain[i], answers[i])) {
        ++n;
        continue;
      }
      if (!robust) robust = std::make_unique<EmbreeScene>(scene, EmbreeScene::Mode::Robust);
      const float r = set.anyHit ? (robust->occluded(set.o[i], set.d[i], set.tnear, set.tfar) ? 1.0f : 0.0f) : [&] {
        const GeoHit h = robust->intersect(set.o[i], set.d[i], set.tnear, set.tfar);
        return h.hit() ? h.t : -1.0f;
      }();
      n += same(r, answers[i]);
    }
    return plain.empty() ? 1.0 : double(n) / double(plain.size());
  };

  nlohmann::json stats = frameStats(frame);
  stats.erase("fragments");
  stats.erase("memory_bytes");
  stats["rays"] = {{"primary", primary.o.size()}, {"ao", ao.o.size()}, {"diffuse", diffuse.o.size()}};
  const std::pair<const char*, RaySet*> sets[] = {{"primary", &primary}, {"ao", &ao}, {"diffuse", &diffuse}};
  nlohmann::json& g = stats["geobench"];
  g["embree"]["build_ms"] = embreeBuild;
  g["embree"]["memory_bytes"] = embree.memoryBytes();
  g["grid"]["build_ms"] = gridBuild;
  g["grid"]["memory_bytes"] = grid.memoryBytes();
  const GridStats& gs = grid.stats();
  g["grid"]["structure"] = {{"top", {gs.top[0], gs.top[1], gs.top[2]}}, {"depth", gs.depth}, {"cells_initial", gs.cellsInitial},
                            {"cells", gs.cellsAfterMerge}, {"references", gs.refs}, {"expanded_faces", gs.expandedFaces},
                            {"merge_passes", gs.mergePasses}, {"lambda1", o.tracers.grid.lambda1}, {"lambda2", o.tracers.grid.lambda2},
                            {"initial_ms", gs.initialMs}, {"merge_ms", gs.mergeMs}, {"expand_ms", gs.expandMs}};
  for (const auto& [name, set] : sets) {
    // The grid twice: one ray at a time, and in batches with several rays in flight (its
    // tracer's uncounted path, reported as mrays_*); the two must answer alike.
    std::vector<float> ea, ga, g1;
    const double te = medianMs(o.repeat, [&] { ea = traceAll(*set, embreeQ(*set)); });
    const double ts = medianMs(o.repeat, [&] { g1 = traceAll(*set, gridQ(grid, *set)); });
    const double tg = medianMs(o.repeat, [&] { ga = traceAllGrid(*set, grid); });
    const double n = double(set->o.size());
    g["embree"][std::string("mrays_") + name] = n / te * 1e-3;
    g["grid"][std::string("mrays_") + name] = n / tg * 1e-3;
    g["grid"][std::string("mrays_single_") + name] = n / ts * 1e-3;
    g["embree"][std::string("agreement_") + name] = 1.0;
    g["grid"][std::string("agreement_") + name] = agreement(ea, ga);
    g["grid"][std::string("agreement_robust_") + name] = robustAgreement(*set, ea, ga);
    LT_CHECK(g1 == ga, "the grid's batch and one-ray answers differ on the ", name, " rays");
  }

  // Embree with 8- and 16-wide packets on the same primary rays (rtcIntersect8/16).
  g["embree"]["flags"] = "default scene flags, HIGH build quality";
  {
    std::vector<float> single = traceAll(primary, embreeQ(primary));
    for (int width : {8, 16}) {
      std::vector<GeoHit> hits(primary.o.size());
      const double t = medianMs(o.repeat, [&] {
        parallelFor(tbb::blocked_range<size_t>(0, primary.o.size(), 1024), [&](const tbb::blocked_range<size_t>& r) {
          embree.intersectPackets(&primary.o[r.begin()], &primary.d[r.begin()], r.end() - r.begin(), primary.tnear, primary.tfar,
                                  width, &hits[r.begin()]);
        });
      });
      std::vector<float> packet(hits.size());
      for (size_t i = 0; i < hits.size(); ++i) packet[i] = hits[i].hit() ? hits[i].t : -1.0f;
      g["embree"][cat("mrays_primary_packet", width)] = double(primary.o.size()) / t * 1e-3;
      g["embree"][cat("agreement_primary_packet", width)] = agreement(single, packet);
    }
  }
  // The grid's work per ray (counted in a separate pass): cells stepped, triangles tested,
  // traversals ended by the step cap.
  {
    uint64_t steps = 0, tests = 0, giveUps = 0, rays = 0;
    for (const auto& [name, set] : sets) {
      uint64_t s0 = 0, t0 = 0;
      for (size_t i = 0; i < set->o.size(); ++i) {
        TraversalCounts c;
        if (set->anyHit) grid.occluded(set->o[i], set->d[i], set->tnear, set->tfar, &c);
        else grid.intersect(set->o[i], set->d[i], set->tnear, set->tfar, &c);
        s0 += c.steps, t0 += c.tests, giveUps += c.giveUps;
      }
      const double n = double(std::max<size_t>(set->o.size(), 1));
      g["grid"][std::string("steps_per_ray_") + name] = double(s0) / n;
      g["grid"][std::string("tests_per_ray_") + name] = double(t0) / n;
      steps += s0, tests += t0, rays += set->o.size();
    }
    g["grid"]["steps_per_ray"] = double(steps) / double(std::max<uint64_t>(rays, 1));
    g["grid"]["tests_per_ray"] = double(tests) / double(std::max<uint64_t>(rays, 1));
    g["grid"]["give_ups"] = giveUps;
  }

  // --device gpu: the CPU's grid, uploaded, walked on the GPU over the same rays (GL timer
  // queries; on a software rasterizer they are CPU times): MRays/s, agreement with plain Embree
  // and with the CPU grid.
  if (o.run.device == "gpu") {
    const std::shared_ptr<GpuContext> gpu = openGpu();
    // A GPU grid's walks over every ray set: GPU ms (median of --repeat after a warm-up that
    // compiles), MRays/s, agreement with plain Embree and with the CPU grid.
    auto walkOnGpu = [&](const Tracer& tracer, nlohmann::json& out) {
      for (const auto& [name, set] : sets) {
        std::vector<IrregularGrid::Query> q(set->o.size());
        for (size_t i = 0; i < q.size(); ++i) q[i] = {set->o[i], set->d[i], set->tnear, set->tfar};
        std::vector<GeoHit> hits(q.size());
        traceGpuGrid(tracer, q, set->anyHit, hits);
        std::vector<double> ms;
        for (int r = 0; r < o.repeat; ++r) ms.push_back(traceGpuGrid(tracer, q, set->anyHit, hits));
        std::vector<float> answers(q.size());
        for (size_t i = 0; i < q.size(); ++i) answers[i] = set->anyHit ? (hits[i].hit() ? 1.0f : 0.0f) : hits[i].hit() ? hits[i].t : -1.0f;
        const double n = double(set->o.size()), med = median(ms);
        out[std::string("gpu_ms_") + name] = med;
        out[std::string("mrays_") + name] = med > 0.0 ? n / med * 1e-3 : 0.0;
        out[std::string("agreement_") + name] = agreement(traceAll(*set, embreeQ(*set)), answers);
        out[std::string("agreement_cpu_grid_") + name] = agreement(traceAllGrid(*set, grid), answers);
      }
    };
    const BuiltTracer onGpu = buildGpuTracer("grid", frame, to, *gpu);
    nlohmann::json& gg = g["grid_gpu"];
    gg["memory_bytes"] = onGpu.memoryBytes;
    gg["build"] = "cpu";  // the structure is the CPU's, uploaded once
    gg["build_ms"] = gridBuild;
    walkOnGpu(*onGpu.tracer, gg);
    // The grid built on the GPU: all four steps and the packing there (gpu/gpu_grid_build.h),
    // the CPU's cells. Medians of --repeat builds after a warm-up, then its walks over the same
    // rays.
    nlohmann::json& gb = g["grid_gpu_build"];
    GpuGridBuildStats bs;
    BuiltTracer gpuBuilt = buildGpuGridOnGpu(frame, o.tracers.grid, &grid, *gpu, bs);  // warm-up
    std::vector<double> buildGpu, buildWall;
    for (int r = 0; r < o.repeat; ++r) {
      gpuBuilt = buildGpuGridOnGpu(frame, o.tracers.grid, &grid, *gpu, bs);
      buildGpu.push_back(bs.gpuMs), buildWall.push_back(bs.wallMs);
    }
    gb["build"] = "gpu";
    gb["steps_on_gpu"] = "initial grid, refinement, merging, expansion, packing";
    gb["build_ms"] = median(buildGpu);
    gb["build_wall_ms"] = median(buildWall);
    gb["build_ms_by_step"] = {{"top_cells", bs.topMs}, {"leaves", bs.leavesMs}, {"merging", bs.mergeMs},
                              {"expansion", bs.expandMs}, {"packing", bs.packMs}};
    gb["cells"] = bs.cells;
    gb["cells_initial"] = bs.cellsInitial;
    gb["merge_rounds"] = bs.mergeRounds;
    gb["expanded_faces"] = bs.expandedFaces;
    gb["references"] = bs.refs;
    gb["memory_bytes"] = bs.memoryBytes;
    // The CPU build of the same configuration (timed above): the same cells, references and faces.
    gb["cpu_twin"] = {{"build_ms", gridBuild}, {"cells", grid.cells().size()}, {"references", grid.refs().size()},
                      {"memory_bytes", grid.memoryBytes()},
                      {"same_cells", grid.cells().size() == bs.cells && grid.refs().size() == bs.refs &&
                                         grid.stats().expandedFaces == bs.expandedFaces}};
    gb["cpu_full_build"] = {{"build_ms", gridBuild}, {"cells", grid.cells().size()}, {"references", grid.refs().size()},
                            {"memory_bytes", grid.memoryBytes()}};
    walkOnGpu(*gpuBuilt.tracer, gb);
    stats["gpu"] = gpuStats(*gpu);
  }

  std::ostringstream sweep;
  if (o.sweep) {
    // λ1 × λ2 (Pérard-Gayot et al. 2017): per setting the build, the size, MRays/s of the three ray sets, the
    // speed relative to the Embree times measured above in this run, and the worst agreement.
    sweep << "lambda1,lambda2,build_ms,cells,references,memory_bytes,mrays_primary,mrays_ao,mrays_diffuse,"
             "x_embree_primary,x_embree_ao,x_embree_diffuse,agreement_min\n";
    std::vector<std::vector<float>> embreeAnswers;
    for (const auto& [name, set] : sets) embreeAnswers.push_back(traceAll(*set, embreeQ(*set)));
    for (float l1 : {0.03f, 0.06f, 0.12f, 0.25f, 0.5f, 1.0f, 2.0f})
      for (float l2 : {0.6f, 1.2f, 2.4f, 4.8f}) {
        GridConfig gc = o.tracers.grid;
        gc.lambda1 = l1, gc.lambda2 = l2;
        std::unique_ptr<IrregularGrid> sg;
        const double b = medianMs(1, [&] { sg = std::make_unique<IrregularGrid>(scene, gc); });
        sweep << l1 << "," << l2 << "," << b << "," << sg->stats().cellsAfterMerge << "," << sg->stats().refs << "," << sg->memoryBytes();
        std::ostringstream ratios;
        double worst = 1.0;
        size_t i = 0;
        for (const auto& [name, set] : sets) {
          std::vector<float> answers;
          const double t = medianMs(o.repeat, [&] { answers = traceAllGrid(*set, *sg); });
          const double mrays = double(set->o.size()) / t * 1e-3;
          sweep << "," << mrays;
          ratios << "," << mrays / g["embree"][std::string("mrays_") + name].get<double>();
          worst = std::min(worst, agreement(embreeAnswers[i++], answers));
        }
        sweep << ratios.str() << "," << worst << "\n";
      }
  }

  {
    ensureDirectory(o.run.output, "-o");
    if (o.sweep) writeFileAtomic((fs::path(o.run.output) / "geobench_sweep.csv").string(), sweep.str());
  }
  writeStats(o.run.statsPath, stats.dump(2));
  if (!o.run.quiet) {
    std::cout << "geobench: " << scene.name << " (" << scene.triangleCount() << " triangles), " << cam.width() << "x"
              << cam.height() << " primary rays\n"
              << std::left << std::setw(15) << "tracer" << std::right << std::setw(10) << "build ms" << std::setw(10) << "MiB ";
    for (const auto& [name, set] : sets) std::cout << std::setw(14) << (std::string("MR/s ") + name) << std::setw(10) << "agree";
    std::cout << "\n" << std::fixed;
    for (const char* t : {"embree", "grid", "grid_gpu", "grid_gpu_build"}) {
      if (!g.contains(t)) continue;
      std::cout << std::left << std::setw(15) << t << std::right << std::setw(10) << std::setprecision(1) << g[t]["build_ms"].get<double>()
                << std::setw(10) << std::setprecision(1) << double(g[t]["memory_bytes"].get<size_t>()) / 1048576.0;
      for (const auto& [name, set] : sets)
        std::cout << std::setw(14) << std::setprecision(2) << g[t][std::string("mrays_") + name].get<double>() << std::setw(10)
                  << std::setprecision(5) << g[t][std::string("agreement_") + name].get<double>();
      std::cout << "\n";
    }
    std::cout << "embree packets (primary): 8-wide " << std::setprecision(2) << g["embree"]["mrays_primary_packet8"].get<double>()
              << " MRays/s, 16-wide " << g["embree"]["mrays_primary_packet16"].get<double>() << " MRays/s; grid "
              << g["grid"]["steps_per_ray"].get<double>() << " cells and " << g["grid"]["tests_per_ray"].get<double>()
              << " triangle tests per ray\n";
    if (o.sweep) std::cout << "λ1 × λ2 sweep (grid):\n" << sweep.str();
  }
  return 0;
}

}  // namespace lt
