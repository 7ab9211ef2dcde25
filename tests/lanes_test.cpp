// The lane helpers every vector loop is built on (util/lanes-inl.h), on every vector target this
// CPU runs: max and min are std::max and std::min bit for bit — which operand wins on ties (−0
// against +0) and on NaN in either place is what keeps the lane marches equal to the scalar
// ones (Highway's own Max returns the other operand on x86 and propagates NaN on Arm) — and the
// record transposition reads every lane's record from anywhere in memory.
#include <algorithm>
#include <bit>
#include <cstdint>
#include <limits>
#include <map>
#include <random>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "lanes_test.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep

#include <hwy/highway.h>

#include "layertrace/util/lanes-inl.h"

HWY_BEFORE_NAMESPACE();
namespace lt::HWY_NAMESPACE {

/// max[i], min[i] = the lanes' vmax / vmin of a[i], b[i]; n a multiple of 64.
void laneMaxMin(const float* a, const float* b, float* max, float* min, size_t n) {
  using namespace lanes;
  for (size_t i = 0; i < n; i += laneCount()) {
    store(max + i, vmax(loadF(a + i), loadF(b + i)));
    store(min + i, vmin(loadF(a + i), loadF(b + i)));
  }
}

/// out[f * lanes + j] = field f of the record at rows[j]; returns the lane count.
size_t laneTranspose(const float* const* rows, float* out) {
  using namespace lanes;
  VF field[8];
  transposeRecords(rows, field);
  for (int f = 0; f < 8; ++f) store(out + size_t(f) * laneCount(), field[f]);
  return laneCount();
}

}  // namespace lt::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
#include "test_util.h"

namespace lt {
HWY_EXPORT(laneMaxMin);
HWY_EXPORT(laneTranspose);

namespace {

TEST(Lanes, MaxMinAreStdMaxMinBitForBit) {
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  const float special[] = {-inf, -1.5f, -0.0f, 0.0f, std::numeric_limits<float>::denorm_min(), 1.5f, inf, nan, -nan, 1.5f};
  std::vector<float> a, b;
  for (float x : special)
    for (float y : special) a.push_back(x), b.push_back(y);
  while (a.size() % 64) a.push_back(0.0f), b.push_back(-0.0f);
  auto bits = [](float f) { return std::bit_cast<uint32_t>(f); };
  size_t targets = 0;
  test::forEachSimdTarget([&](const SimdTarget&) {
    ++targets;
    std::vector<float> mx(a.size()), mn(a.size());
    HWY_DYNAMIC_DISPATCH(laneMaxMin)(a.data(), b.data(), mx.data(), mn.data(), a.size());
    for (size_t i = 0; i < a.size(); ++i) {
      ASSERT_EQ(bits(mx[i]), bits(std::max(a[i], b[i]))) << a[i] << ", " << b[i];
      ASSERT_EQ(bits(mn[i]), bits(std::min(a[i], b[i]))) << a[i] << ", " << b[i];
    }
  });
  EXPECT_GE(targets, 1u);
}

TEST(Lanes, TransposeReadsEachLanesRecord) {
  std::vector<float> pool(64 * 8 * 3);
  for (size_t i = 0; i < pool.size(); ++i) pool[i] = float(i) + 0.25f;
  std::mt19937 rng{uint32_t(test::testSeed())};
  // The lanes each target must have: dispatch really switched when the count follows the target.
  const std::map<std::string, size_t> expectedLanes{{"avx512", 16}, {"avx512-dl", 16}, {"avx2", 8}, {"sse4", 4},
                                                    {"neon", 4},    {"emu128", 4},     {"scalar", 1}};
  std::set<size_t> counts;
  test::forEachSimdTarget([&](const SimdTarget& t) {
    counts.insert(simdLaneCount(t));
    for (int round = 0; round < 20; ++round) {
      const float* rows[64];
      for (const float*& r : rows) r = &pool[size_t(rng() % (pool.size() - 8))];  // unaligned, anywhere
      std::vector<float> out(8 * 64);
      const size_t n = HWY_DYNAMIC_DISPATCH(laneTranspose)(rows, out.data());
      if (expectedLanes.count(t.name)) {
        ASSERT_EQ(n, expectedLanes.at(t.name)) << t.name;
      }
      ASSERT_EQ(n, simdLaneCount(t)) << t.name;
      for (size_t j = 0; j < n; ++j)
        for (size_t f = 0; f < 8; ++f) ASSERT_EQ(out[f * n + j], rows[j][f]) << t.name << " lane " << j << " field " << f;
    }
  });
  if (simdTargets().size() > 1) {
    EXPECT_GT(counts.size(), 1u) << "every target ran with the same lanes: dispatch did not switch";
  }
}

TEST(Lanes, TargetsListTheBestFirstAndDispatchFollowsTheChoice) {
  const std::vector<SimdTarget> all = simdTargets();
  ASSERT_FALSE(all.empty());
  EXPECT_EQ(activeSimdTarget().bits, all.front().bits);
  for (size_t i = 1; i < all.size(); ++i) EXPECT_LT(all[i - 1].bits, all[i].bits) << "Highway: lower bits are better targets";
  {
    const ScopedSimdTarget only(all.back());
    EXPECT_EQ(activeSimdTarget().bits, all.back().bits);
    {
      const ScopedSimdTarget inner(all.front());
      EXPECT_EQ(activeSimdTarget().bits, all.front().bits);
    }
    EXPECT_EQ(activeSimdTarget().bits, all.back().bits) << "an inner scope restores the outer one's choice";
    simdLaneCount(all.front());
    EXPECT_EQ(activeSimdTarget().bits, all.back().bits) << "simdLaneCount keeps the scope's choice";
  }
  EXPECT_EQ(activeSimdTarget().bits, all.front().bits);
}

}  // namespace
}  // namespace lt
#endif
