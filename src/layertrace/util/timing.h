// Timing helpers for benchmarks: the machine is noisy, so report medians of repeated runs.
#pragma once

#include <algorithm>
#include <chrono>
#include <vector>

namespace lt {

inline double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

/// Median wall time of `repeat` calls of f, in milliseconds, after one discarded warm-up call
/// (the first run pays for cold memory: page faults on fresh buffers, cold caches).
template <typename F>
double medianMs(int repeat, F&& f) {
  f();
  std::vector<double> t;
  for (int i = 0; i < repeat; ++i) {
    const auto s = std::chrono::steady_clock::now();
    f();
    t.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - s).count());
  }
  return median(t);
}

}  // namespace lt
