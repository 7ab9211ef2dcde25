// Sixteen float / int32 lanes in an AVX-512 register, for the hand-vectorized loops that are the
// research subject (the HSSR march in lanes, the pyramid's level-1 merge): GCC vector extensions
// for the arithmetic, intrinsics only for what they lack (comparisons into k-register lane masks,
// blends, masked loads).
//
// Only GCC on x86-64 compiles these (LT_SIMD512 = 1). Everything here is compiled for AVX-512
// F/VL/BW/DQ by its own target pragma, and so must be the functions that use it (the same
// push_options / target region around them): a build for x86-64-v2 then still runs on any CPU,
// and a caller takes the lanes only where simd512Available() says the CPU has them, keeping a
// portable path beside them. (Not `target_clones`: GCC lowers 64-byte vector types to scalar
// code inside its clones of an x86-64-v2 build.)
#pragma once

#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__)
#define LT_SIMD512 1
#include <immintrin.h>

#include <cstdint>
#include <cstring>

#pragma GCC push_options
#pragma GCC target("avx512f,avx512vl,avx512bw,avx512dq")

namespace lt::simd512 {

constexpr int kLanes = 16;
using F = float __attribute__((vector_size(64)));
using I = int32_t __attribute__((vector_size(64)));
using Q = int64_t __attribute__((vector_size(64)));  // eight 64-bit lanes
using F8 = float __attribute__((vector_size(32)));

template <class V, class T>
inline V load(const T* p) {
  V v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
template <class V, class T>
inline void store(T* p, V v) {
  std::memcpy(p, &v, sizeof v);
}

/// A lane mask (one bit per lane) and the comparisons that make it: ordered and quiet like
/// C's <, <=, >, >=, == (false on NaN), unordered for != (true on NaN).
struct M {
  __mmask16 bits;
};
// (k-register operations, so that masks do not travel through general registers)
inline M operator&(M a, M b) { return {_kand_mask16(a.bits, b.bits)}; }
inline M operator|(M a, M b) { return {_kor_mask16(a.bits, b.bits)}; }
inline M operator~(M a) { return {_knot_mask16(a.bits)}; }
inline M operator^(M a, M b) { return {_kxor_mask16(a.bits, b.bits)}; }
inline M lt(F a, F b) { return {_mm512_cmp_ps_mask((__m512)a, (__m512)b, _CMP_LT_OQ)}; }
inline M le(F a, F b) { return {_mm512_cmp_ps_mask((__m512)a, (__m512)b, _CMP_LE_OQ)}; }
inline M gt(F a, F b) { return {_mm512_cmp_ps_mask((__m512)a, (__m512)b, _CMP_GT_OQ)}; }
inline M ge(F a, F b) { return {_mm512_cmp_ps_mask((__m512)a, (__m512)b, _CMP_GE_OQ)}; }
inline M eq(F a, F b) { return {_mm512_cmp_ps_mask((__m512)a, (__m512)b, _CMP_EQ_OQ)}; }
inline M ne(F a, F b) { return {_mm512_cmp_ps_mask((__m512)a, (__m512)b, _CMP_NEQ_UQ)}; }
inline M lt(I a, I b) { return {_mm512_cmplt_epi32_mask((__m512i)a, (__m512i)b)}; }
inline M gt(I a, I b) { return {_mm512_cmpgt_epi32_mask((__m512i)a, (__m512i)b)}; }
inline M ge(I a, I b) { return {_mm512_cmpge_epi32_mask((__m512i)a, (__m512i)b)}; }
inline M eq(I a, I b) { return {_mm512_cmpeq_epi32_mask((__m512i)a, (__m512i)b)}; }
inline M ne(I a, I b) { return {_mm512_cmpneq_epi32_mask((__m512i)a, (__m512i)b)}; }
/// The same comparisons limited to the lanes of a mask — `lt(m, a, b)` is m & lt(a, b) — in one
/// masked compare instead of a compare and a k-register AND.
inline M lt(M m, F a, F b) { return {_mm512_mask_cmp_ps_mask(m.bits, (__m512)a, (__m512)b, _CMP_LT_OQ)}; }
inline M le(M m, F a, F b) { return {_mm512_mask_cmp_ps_mask(m.bits, (__m512)a, (__m512)b, _CMP_LE_OQ)}; }
inline M eq(M m, F a, F b) { return {_mm512_mask_cmp_ps_mask(m.bits, (__m512)a, (__m512)b, _CMP_EQ_OQ)}; }
inline M lt(M m, I a, I b) { return {_mm512_mask_cmplt_epi32_mask(m.bits, (__m512i)a, (__m512i)b)}; }
inline M eq(M m, I a, I b) { return {_mm512_mask_cmpeq_epi32_mask(m.bits, (__m512i)a, (__m512i)b)}; }
inline M ge(M m, I a, I b) { return {_mm512_mask_cmpge_epi32_mask(m.bits, (__m512i)a, (__m512i)b)}; }
inline M ne(M m, I a, I b) { return {_mm512_mask_cmpneq_epi32_mask(m.bits, (__m512i)a, (__m512i)b)}; }
/// m & ~gt(a, b), m & ~lt(a, b), m & ~ge(a, b): the negated predicates are unordered (true on NaN), as ~ is.
inline M notGt(M m, F a, F b) { return {_mm512_mask_cmp_ps_mask(m.bits, (__m512)a, (__m512)b, _CMP_NGT_UQ)}; }
inline M notLt(M m, F a, F b) { return {_mm512_mask_cmp_ps_mask(m.bits, (__m512)a, (__m512)b, _CMP_NLT_UQ)}; }
inline M notGe(M m, F a, F b) { return {_mm512_mask_cmp_ps_mask(m.bits, (__m512)a, (__m512)b, _CMP_NGE_UQ)}; }
/// a & ~b in one k-register instruction.
inline M andNot(M a, M b) { return {_kandn_mask16(b.bits, a.bits)}; }
/// Lanes where i ∉ [0, n) for n ≥ 0: one unsigned compare (a negative i is a large unsigned one).
inline M outside(I i, I n) { return {_mm512_cmpge_epu32_mask((__m512i)i, (__m512i)n)}; }
/// m ? a : b per lane.
inline F sel(M m, F a, F b) { return (F)_mm512_mask_blend_ps(m.bits, (__m512)b, (__m512)a); }
inline I sel(M m, I a, I b) { return (I)_mm512_mask_blend_epi32(m.bits, (__m512i)b, (__m512i)a); }

/// std::max / std::min as libstdc++ writes them (a < b ? b : a; b < a ? b : a): the same
/// operand wins on ties, −0 and NaN as in the scalar code the lanes must match bit for bit.
/// One instruction each: x86's MAXPS(x, y) is x > y ? x : y and MINPS(x, y) x < y ? x : y,
/// the second operand on ties and NaN — so MAXPS(b, a) is std::max(a, b) and MINPS(b, a)
/// std::min(a, b) in every case (GCC keeps the intrinsics' operand order without -ffast-math).
/// (Before: a compare into a mask and a blend, 1 017 → … instructions in the HSSR step.)
/// (The masked form with every lane set: GCC 12's unmasked one warns on its undefined source.)
inline F vmax(F a, F b) { return (F)_mm512_mask_max_ps((__m512)a, 0xffff, (__m512)b, (__m512)a); }
inline F vmin(F a, F b) { return (F)_mm512_mask_min_ps((__m512)a, 0xffff, (__m512)b, (__m512)a); }

/// std::max / std::min of int32 lanes, and floor (round toward −∞) of float lanes.
inline I imax(I a, I b) { return (I)_mm512_mask_max_epi32((__m512i)a, 0xffff, (__m512i)a, (__m512i)b); }
inline I imin(I a, I b) { return (I)_mm512_mask_min_epi32((__m512i)a, 0xffff, (__m512i)a, (__m512i)b); }
/// |a| (the sign bit cleared, as std::abs).
inline F vabs(F a) { return (F)((I)a & 0x7fffffff); }
inline F vfloor(F a) { return (F)_mm512_mask_roundscale_ps((__m512)a, 0xffff, (__m512)a, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC); }

/// Blocks (128 bits) 0 and 2 of a, then 0 and 2 of b; blocks13: 1 and 3 of each.
inline F blocks02(F a, F b) { return __builtin_shufflevector(a, b, 0, 1, 2, 3, 8, 9, 10, 11, 16, 17, 18, 19, 24, 25, 26, 27); }
inline F blocks13(F a, F b) { return __builtin_shufflevector(a, b, 4, 5, 6, 7, 12, 13, 14, 15, 20, 21, 22, 23, 28, 29, 30, 31); }

/// m[i] lane j becomes m[j] lane i: a 16 × 16 transpose of floats in 64 shuffles — 4 × 4
/// transposes inside the 128-bit blocks (32-bit, then 64-bit interleaves), then a 4 × 4
/// transpose of the blocks.
inline void transpose16(F m[16]) {
  F a[16], b[16];
  for (int j = 0; j < 16; j += 2) {
    a[j] = __builtin_shufflevector(m[j], m[j + 1], 0, 16, 1, 17, 4, 20, 5, 21, 8, 24, 9, 25, 12, 28, 13, 29);
    a[j + 1] = __builtin_shufflevector(m[j], m[j + 1], 2, 18, 3, 19, 6, 22, 7, 23, 10, 26, 11, 27, 14, 30, 15, 31);
  }
  for (int g = 0; g < 16; g += 4)
    for (int h = 0; h < 2; ++h) {
      b[g + 2 * h] = __builtin_shufflevector(a[g + h], a[g + 2 + h], 0, 1, 16, 17, 4, 5, 20, 21, 8, 9, 24, 25, 12, 13, 28, 29);
      b[g + 2 * h + 1] = __builtin_shufflevector(a[g + h], a[g + 2 + h], 2, 3, 18, 19, 6, 7, 22, 23, 10, 11, 26, 27, 14, 15, 30, 31);
    }
  // b[4q + c]: block B holds rows 4q … 4q + 3 of column 4B + c
  for (int c = 0; c < 4; ++c) {
    const F t0 = blocks02(b[c], b[4 + c]), t1 = blocks13(b[c], b[4 + c]);
    const F t2 = blocks02(b[8 + c], b[12 + c]), t3 = blocks13(b[8 + c], b[12 + c]);
    m[c] = blocks02(t0, t2), m[4 + c] = blocks02(t1, t3), m[8 + c] = blocks13(t0, t2), m[12 + c] = blocks13(t1, t3);
  }
}

/// Sixteen rows of eight floats, row j in the low half of r[j] and row j + 8 in its high half
/// (j < 8), as eight registers: lane j of field[f] is float f of row j. An 8 × 8 transpose done on
/// both register halves at once (unpack, shuffle, then 128-bit blocks) in 24 shuffles — what a
/// lane march uses to read one 32-byte record per lane, cheaper here than eight gathers.
inline void transposeRows8(const F r[8], F field[8]) {
  F u[8], v[8];
  for (int j = 0; j < 4; ++j) {
    u[2 * j] = __builtin_shufflevector(r[2 * j], r[2 * j + 1], 0, 16, 1, 17, 4, 20, 5, 21, 8, 24, 9, 25, 12, 28, 13, 29);
    u[2 * j + 1] = __builtin_shufflevector(r[2 * j], r[2 * j + 1], 2, 18, 3, 19, 6, 22, 7, 23, 10, 26, 11, 27, 14, 30, 15, 31);
  }
  for (int j = 0; j < 2; ++j) {
    const F &a = u[4 * j], &b = u[4 * j + 1], &c = u[4 * j + 2], &d = u[4 * j + 3];
    v[4 * j] = __builtin_shufflevector(a, c, 0, 1, 16, 17, 4, 5, 20, 21, 8, 9, 24, 25, 12, 13, 28, 29);
    v[4 * j + 1] = __builtin_shufflevector(a, c, 2, 3, 18, 19, 6, 7, 22, 23, 10, 11, 26, 27, 14, 15, 30, 31);
    v[4 * j + 2] = __builtin_shufflevector(b, d, 0, 1, 16, 17, 4, 5, 20, 21, 8, 9, 24, 25, 12, 13, 28, 29);
    v[4 * j + 3] = __builtin_shufflevector(b, d, 2, 3, 18, 19, 6, 7, 22, 23, 10, 11, 26, 27, 14, 15, 30, 31);
  }
  for (int f = 0; f < 4; ++f) {
    field[f] = __builtin_shufflevector(v[f], v[f + 4], 0, 1, 2, 3, 16, 17, 18, 19, 8, 9, 10, 11, 24, 25, 26, 27);
    field[f + 4] = __builtin_shufflevector(v[f], v[f + 4], 4, 5, 6, 7, 20, 21, 22, 23, 12, 13, 14, 15, 28, 29, 30, 31);
  }
}

/// Row j (8 floats) and row j + 8 as one register: the input of transposeRows8.
inline F joinRows(F8 lo, F8 hi) { return __builtin_shufflevector(lo, hi, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15); }

/// Lane refill over `kGroups` groups of sixteen lanes stepped in turn (the HSSR and SSR lane
/// marches): `fill(ln, j)` gives lane j of a group its next item (false when none is left: the
/// lane stays empty), `step(ln)` advances every live lane of a group and returns the mask of the
/// lanes that finished, `done(ln, j)` takes a finished lane's result before the lane is refilled,
/// and `refilled(ln)` runs after a group's lanes were (re)filled. With two groups each step can
/// prefetch its lanes' next records while the other group's step hides their latency.
/// Lanes is a lane state with an `int32_t ray[kLanes]` member (−1: an empty lane); every group
/// starts value-initialized and empty.
template <int kGroups, class Lanes, class Fill, class Step, class Done, class Refilled>
void runLaneGroups(Lanes (&lanes)[kGroups], Fill&& fill, Step&& step, Done&& done, Refilled&& refilled) {
  int live = 0;
  for (Lanes& ln : lanes) {
    ln = Lanes{};
    for (int32_t& r : ln.ray) r = -1;
    for (int j = 0; j < kLanes; ++j) live += fill(ln, j);
    refilled(ln);
  }
  while (live > 0) {
    uint32_t finished[kGroups];
    for (int g = 0; g < kGroups; ++g) finished[g] = step(lanes[g]);
    for (int g = 0; g < kGroups; ++g) {
      if (!finished[g]) continue;
      for (uint32_t m = finished[g]; m; m &= m - 1) {
        const int j = __builtin_ctz(m);
        done(lanes[g], j);
        live += int(fill(lanes[g], j)) - 1;
      }
      refilled(lanes[g]);
    }
  }
}

/// transpose16 over 16 rows of 16 floats in memory, `in` to `out` (callable from code compiled
/// for any CPU, as the tests do; run it only where simd512Available()).
inline void transpose16(const float* in, float* out) {
  F m[16];
  for (int i = 0; i < 16; ++i) m[i] = load<F>(in + 16 * i);
  transpose16(m);
  for (int i = 0; i < 16; ++i) store(out + 16 * i, m[i]);
}

/// vmax and vmin over sixteen lanes in memory (for the tests, as transpose16 above).
inline void maxMin16(const float* a, const float* b, float* max, float* min) {
  store(max, vmax(load<F>(a), load<F>(b)));
  store(min, vmin(load<F>(a), load<F>(b)));
}

}  // namespace lt::simd512

#pragma GCC pop_options

namespace lt {
/// Whether this CPU runs the code compiled under the target region above.
inline bool simd512Available() {
  static const bool cpu = __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl") &&
                          __builtin_cpu_supports("avx512bw") && __builtin_cpu_supports("avx512dq");
  return cpu;
}
}  // namespace lt

#else
#define LT_SIMD512 0
namespace lt {
inline bool simd512Available() { return false; }
}  // namespace lt
#endif
