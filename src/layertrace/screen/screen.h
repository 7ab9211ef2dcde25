// Layer: screen/ holds the image-space structures, each with its tracer: SSR (seed 001), the
// interval pyramid and HSSR (seed 000), the Hi-Z min/max pyramid and march, Widmer's plane/box quad-tree (seed 002),
// the layered depth cube (seed 004). Every tracer implements trace/'s interface over the
// k-layer arrays of raster/ — except the layered depth cube, which captures the scene along its
// three axes with raster/'s rasterizer. It includes trace/, raster/, scene/ and util/ — never geometry/
// (screen space answers from stored fragments only) and nothing above.
//
// This header includes the layer's public headers.
#pragma once

#include "layertrace/screen/fragment_hit.h"
#include "layertrace/screen/hiz_pyramid.h"
#include "layertrace/screen/hssr_tracer.h"
#include "layertrace/screen/interval_layers.h"
#include "layertrace/screen/interval_pyramid.h"
#include "layertrace/screen/ldc.h"
#include "layertrace/screen/quadtree.h"
#include "layertrace/screen/screen_segment.h"
#include "layertrace/screen/ssr_tracer.h"
