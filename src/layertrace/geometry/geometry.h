// Layer: geometry/ holds the geometric tracers — Embree (the ground truth) and the irregular
// grid (seed 003) — which answer from the scene's triangles. They implement trace/'s interface.
// It includes trace/, raster/ (the packed fragment attributes), scene/ and util/ — never screen/,
// and nothing above.
//
// This header includes the layer's public headers.
#pragma once

#include "layertrace/geometry/embree_scene.h"
#include "layertrace/geometry/geometric_tracer.h"
#include "layertrace/geometry/irregular_grid.h"
