// SSR as the registry sees it (trace/method.h): McGuire and Mara 2014, one layer or all k.
#pragma once

#include "layertrace/ssr/ssr_tracer.h"
#include "layertrace/trace/method.h"

namespace lt {

inline constexpr MethodInfo kSsrMethod{"ssr", TracerKind::Screen, "linear march in screen space against the front layer",
                                       "McGuire and Mara 2014, Efficient GPU Screen-Space Ray Tracing (JCGT)"};
inline constexpr MethodInfo kSsrLayersMethod{"ssr-layers", TracerKind::Screen, "the same march against all k stored intervals per pixel",
                                             "McGuire and Mara 2014, with the k layers of Hofmann et al. 2017"};

/// --ssr-stride, --ssr-jitter, --ssr-max-steps.
std::span<const Param<SsrConfig>> ssrParams();
/// InputError naming the flag for a value out of range.
void validateSsrConfig(const SsrConfig& config);

}  // namespace lt
