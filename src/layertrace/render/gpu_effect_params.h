// The GPU effect passes' parameters (gpu/gpu_effects.h) for an effect of render/effects.h on a
// frame: its kind, ray counts and lengths, seed and rules, with the scene-dependent defaults
// resolved as the CPU renderer resolves them. Only in a build with the GPU back end.
#pragma once

#if LAYERTRACE_HAS_GPU
#include "layertrace/gpu/gpu_effects.h"
#include "layertrace/pipeline/frame.h"
#include "layertrace/render/effects.h"

namespace lt {

GpuEffectParams gpuEffectParams(const Frame& frame, const EffectConfig& config);

}  // namespace lt
#endif
