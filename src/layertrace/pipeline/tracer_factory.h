// Builds any tracer by name for a frame, owning the structure it needs (pyramid, Embree BVH).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "layertrace/pipeline/frame.h"
#include "layertrace/geometry/embree_scene.h"
#include "layertrace/geometry/irregular_grid.h"
#include "layertrace/hybrid/hybrid_tracer.h"
#include "layertrace/screen/hiz_pyramid.h"
#include "layertrace/screen/hssr_tracer.h"
#include "layertrace/screen/interval_pyramid.h"
#include "layertrace/screen/ldc.h"
#include "layertrace/screen/quadtree.h"
#include "layertrace/screen/ssr_tracer.h"

namespace lt {

/// The hybrid's HSSR / Hi-Z intervals (known_space.h solidIntervals): the last stored surface of
/// a complete pixel is this many pixel footprints deep.
inline constexpr float kHybridLastThicknessPx = 20.0f;

/// Options of every tracer (DESIGN.md names): ssr's stride etc., hssr's τ, levels, n_up.
struct TracerOptions {
  SsrConfig ssr;
  PyramidConfig pyramid;
  HssrConfig hssr;
  GridConfig grid;
  QuadtreeConfig quadtree;
  LdcConfig ldc;
  std::string hybridScreen = "hssr";  ///< --hybrid-screen: hssr, hiz, quadtree or ldc
  std::string hybridGeo = "embree";   ///< --hybrid-geo: embree, embree-robust or grid
};

/// Throws InputError naming the option for any invalid value, whichever tracer will run.
void validateTracerOptions(const TracerOptions& options);

/// Known tracer names: ssr, ssr-layers, hiz, hssr, quadtree (screen space, from the camera's
/// layers); ldc (seed 004's view-independent layered depth cube); embree, grid (geometric);
/// hybrid (a screen tracer, then a geometric one where the layers do not know).
inline constexpr const char* kTracerNames = "ssr, ssr-layers, hiz, hssr, quadtree, ldc, hybrid, embree, grid";
/// A tracer that answers from the camera's layers alone (the exhaustive oracle applies to it).
bool isScreenTracer(const std::string& name);
bool isKnownTracer(const std::string& name);

struct BuiltTracer {
  std::unique_ptr<Tracer> tracer;
  std::shared_ptr<IntervalPyramid> pyramid;  ///< hssr, hiz (hssr: may be the frame's, Frame::pyramid)
  std::unique_ptr<Quadtree> quadtree;        ///< quadtree
  std::unique_ptr<LayeredDepthCube> ldc;     ///< ldc
  std::unique_ptr<EmbreeScene> embree;       ///< embree
  std::unique_ptr<IrregularGrid> grid;       ///< grid
  std::unique_ptr<KnownSpace> known;         ///< hybrid: where the layers' knowledge ends
  std::vector<BuiltTracer> parts;            ///< hybrid: its screen and geometric tracers
  double buildMs = 0.0;                      ///< hierarchy / BVH construction
  size_t memoryBytes = 0;                    ///< the structure's bytes
};

/// InputError for an unknown name.
BuiltTracer buildTracer(const std::string& name, const Frame& frame, const TracerOptions& options);

/// The geometric ground truth of classification: Embree in robust (watertight) mode. The
/// "embree" tracer of buildTracer is the fast baseline (default scene flags) that speed claims
/// are measured against.
BuiltTracer buildReference(const Frame& frame);

/// The exhaustive image-space oracle (hssr traversal with one level).
BuiltTracer buildOracle(const Frame& frame);

}  // namespace lt
