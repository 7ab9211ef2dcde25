#include "layertrace/util/simd_targets.h"

#include <hwy/highway.h>
#include <hwy/targets.h>

namespace lt {
namespace {

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

}  // namespace

std::vector<SimdTarget> simdTargets() {
  std::vector<SimdTarget> out;
  // (lower bits are better targets: SupportedAndGeneratedTargets lists them best first)
  for (int64_t t : hwy::SupportedAndGeneratedTargets()) out.push_back({t, nameOf(t)});
  return out;
}

SimdTarget activeSimdTarget() {
  const std::vector<int64_t> t = hwy::SupportedAndGeneratedTargets();
  return t.empty() ? SimdTarget{HWY_STATIC_TARGET, nameOf(HWY_STATIC_TARGET)} : SimdTarget{t.front(), nameOf(t.front())};
}

ScopedSimdTarget::ScopedSimdTarget(const SimdTarget& target) { hwy::SetSupportedTargetsForTest(target.bits); }
ScopedSimdTarget::~ScopedSimdTarget() { hwy::SetSupportedTargetsForTest(0); }

}  // namespace lt
