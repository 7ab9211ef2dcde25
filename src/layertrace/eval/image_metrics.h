// Image comparison metrics of the evaluation.
#pragma once

#include <algorithm>
#include <cmath>
#include <utility>

#include "layertrace/util/image.h"

namespace lt {

/// RMSE and PSNR of `a` against `b` on linear RGB clamped to [0, 1] (the displayable range;
/// PSNR = 10 log10(1 / MSE); 99 dB for identical images).
inline std::pair<double, double> rmsePsnr(const Image& a, const Image& b) {
  double sum = 0.0;
  for (size_t i = 0; i < a.data.size(); ++i) {
    const double d = std::clamp(a.data[i], 0.0f, 1.0f) - std::clamp(b.data[i], 0.0f, 1.0f);
    sum += d * d;
  }
  const double mse = sum / double(std::max<size_t>(a.data.size(), 1));
  return {std::sqrt(mse), mse > 0.0 ? std::min(99.0, 10.0 * std::log10(1.0 / mse)) : 99.0};
}

}  // namespace lt
