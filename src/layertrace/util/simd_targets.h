// The vector targets the lane loops are compiled for (util/lanes-inl.h, Google Highway), which of
// them this CPU runs, and a way to run the loops on one of them: the same answers on every
// target are tested, and `bench --experiment simd` times each.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace lt {

struct SimdTarget {
  int64_t bits = 0;  ///< Highway's target bit (HWY_AVX3, HWY_AVX2, …)
  std::string name;  ///< avx512, avx2, sse4, neon, sve, sve2, emu128 or scalar (the emulations), …
};

/// The targets compiled into this build that this CPU runs, best first.
std::vector<SimdTarget> simdTargets();

/// Float lanes of a vector on `target` (16 for AVX-512, 8 for AVX2, 4 for SSE4 and NEON). Not
/// while another thread runs lane loops (it switches the dispatch for a moment).
size_t simdLaneCount(const SimdTarget& target);

/// The machine a number was measured on, as every statistics file records it (key `machine`):
/// the CPU model, its hardware threads and the vector target the lane loops run on
/// ("AMD EPYC, 2 threads, avx512"), since a ratio to Embree moves with all three.
std::string machineName();

/// The target the lane loops run on now (the best one, or the one a ScopedSimdTarget chose).
SimdTarget activeSimdTarget();

/// While alive, the lane loops run on `target` only (one of simdTargets()); the choice before
/// (the best target, or an enclosing scope's) again afterwards. Dispatch is process-wide: do not
/// change it while other threads run lane loops.
class ScopedSimdTarget {
 public:
  explicit ScopedSimdTarget(const SimdTarget& target);
  ~ScopedSimdTarget();
  ScopedSimdTarget(const ScopedSimdTarget&) = delete;
  ScopedSimdTarget& operator=(const ScopedSimdTarget&) = delete;

 private:
  int64_t previous_;
};

}  // namespace lt
