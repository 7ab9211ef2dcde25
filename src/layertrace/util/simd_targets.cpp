// (Included once per vector target through hwy/foreach_target.h, for each target's lane count.)
#include "layertrace/util/simd_targets.h"

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "layertrace/util/simd_targets.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep

#include <hwy/highway.h>
#include <hwy/targets.h>

#include <fstream>
#include <thread>

HWY_BEFORE_NAMESPACE();
namespace lt::HWY_NAMESPACE {
size_t floatLanes() { return hwy::HWY_NAMESPACE::Lanes(hwy::HWY_NAMESPACE::ScalableTag<float>()); }
}  // namespace lt::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace lt {
namespace {

HWY_EXPORT(floatLanes);

std::string nameOf(int64_t bits) {
  switch (bits) {
#if HWY_ARCH_X86
    case HWY_AVX3_DL: return "avx512-dl";
    case HWY_AVX3: return "avx512";
    case HWY_AVX2: return "avx2";
    case HWY_SSE4: return "sse4";
    case HWY_SSSE3: return "ssse3";
#endif
#if HWY_ARCH_ARM
    case HWY_SVE2: return "sve2";
    case HWY_SVE: return "sve";
    case HWY_NEON: return "neon";
#endif
    case HWY_EMU128: return "emu128";
    case HWY_SCALAR: return "scalar";
    default: break;
  }
  std::string s = hwy::TargetName(bits);
  for (char& c : s) c = char(c >= 'A' && c <= 'Z' ? c - 'A' + 'a' : c);
  return s;
}

/// The target a live ScopedSimdTarget chose (0: none; Highway has no getter for it).
int64_t gScoped = 0;

/// The dispatch table's entry for `target`, as the lane loops would run it; the choice in force
/// before is restored.
size_t lanesOf(int64_t target) {
  hwy::SetSupportedTargetsForTest(target);
  const size_t n = HWY_DYNAMIC_DISPATCH(floatLanes)();
  hwy::SetSupportedTargetsForTest(gScoped);
  return n;
}

}  // namespace

std::vector<SimdTarget> simdTargets() {
  std::vector<SimdTarget> out;
  // (lower bits are better targets: SupportedAndGeneratedTargets lists them best first)
  for (int64_t t : hwy::SupportedAndGeneratedTargets()) out.push_back({t, nameOf(t)});
  return out;
}

SimdTarget activeSimdTarget() {
  const std::vector<int64_t> t = hwy::SupportedAndGeneratedTargets();
  const int64_t best = t.empty() ? int64_t(HWY_STATIC_TARGET) : t.front();
  return {best, nameOf(best)};
}

size_t simdLaneCount(const SimdTarget& target) { return lanesOf(target.bits); }

ScopedSimdTarget::ScopedSimdTarget(const SimdTarget& target) : previous_(gScoped) {
  gScoped = target.bits;
  hwy::SetSupportedTargetsForTest(gScoped);
}
ScopedSimdTarget::~ScopedSimdTarget() {
  gScoped = previous_;
  hwy::SetSupportedTargetsForTest(gScoped);
}

std::string machineName() {
  std::string cpu;
  std::ifstream in("/proc/cpuinfo");
  for (std::string line; cpu.empty() && std::getline(in, line);)
    if (line.rfind("model name", 0) == 0 && line.find(':') != std::string::npos) cpu = line.substr(line.find(':') + 2);
  if (cpu.empty()) cpu = "unknown CPU";
  return cpu + ", " + std::to_string(std::thread::hardware_concurrency()) + " threads, " + activeSimdTarget().name;
}

}  // namespace lt
#endif
