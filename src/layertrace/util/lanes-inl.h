// Vector lanes for the hand-vectorized loops that are the research subject (the SSR and HSSR
// marches in lanes, the pyramid's level-1 merge, the grid walk), written once with Google
// Highway and compiled for every target it builds (SSE4, AVX2, AVX-512 on x86-64; NEON, SVE on
// Arm; the EMU128 emulation everywhere). A loop's file includes this header per target through
// hwy/foreach_target.h and picks the best target at run time (HWY_DYNAMIC_DISPATCH).
//
// The lanes must answer bit for bit like the scalar code they replace, on every target. What
// this header adds to Highway's ops is what that takes:
// - comparisons that return one mask type (float lanes) for float and int32 operands, with C's
//   quiet ordered semantics (false on NaN) and an unordered != (true on NaN);
// - vmax / vmin with libstdc++'s std::max / std::min operand rule (ties and NaN keep the first
//   operand): Highway's Max/Min follow the instruction set (x86 MAXPS returns its second operand
//   on ties and NaN, Arm's FMAX propagates NaN), so they are built from a compare and a select,
//   or from MAXPS with swapped operands where that is the same;
// - the transposition of one 32-byte record per lane into eight vectors of fields;
// - the lane-refill loop that every lane march shares.
//
// Per-target include guard (Highway's convention): this file is included once per target.
#if defined(LAYERTRACE_UTIL_LANES_INL_H_) == defined(HWY_TARGET_TOGGLE)
#ifdef LAYERTRACE_UTIL_LANES_INL_H_
#undef LAYERTRACE_UTIL_LANES_INL_H_
#else
#define LAYERTRACE_UTIL_LANES_INL_H_
#endif

#include <bit>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>

#include <hwy/highway.h>

HWY_BEFORE_NAMESPACE();
namespace lt::HWY_NAMESPACE::lanes {

namespace hn = hwy::HWY_NAMESPACE;

using DF = hn::ScalableTag<float>;
using DI = hn::ScalableTag<int32_t>;
using VF = hn::Vec<DF>;
using VI = hn::Vec<DI>;
/// The one mask type of the lane code (float lanes; int32 comparisons are rebound to it).
using M = hn::Mask<DF>;

/// The most lanes a vector of this target holds (the size of the per-lane state arrays); Lanes(d)
/// is the count at run time (the same but on scalable targets).
constexpr size_t kMaxLanes = hn::MaxLanes(DF());
static_assert(kMaxLanes <= 64, "lane masks are read into 64-bit words");

inline size_t laneCount() { return hn::Lanes(DF()); }

inline VF splat(float x) { return hn::Set(DF(), x); }
inline VI splat(int32_t x) { return hn::Set(DI(), x); }
inline VF loadF(const float* p) { return hn::LoadU(DF(), p); }
inline VI loadI(const int32_t* p) { return hn::LoadU(DI(), p); }
inline void store(float* p, VF v) { hn::StoreU(v, DF(), p); }
inline void store(int32_t* p, VI v) { hn::StoreU(v, DI(), p); }

inline M toM(hn::Mask<DI> m) { return hn::RebindMask(DF(), m); }
inline hn::Mask<DI> toMI(M m) { return hn::RebindMask(DI(), m); }

// Comparisons (float: ordered and quiet as C's, except ne, which is unordered like C's !=).
inline M lt(VF a, VF b) { return hn::Lt(a, b); }
inline M le(VF a, VF b) { return hn::Le(a, b); }
inline M gt(VF a, VF b) { return hn::Gt(a, b); }
inline M ge(VF a, VF b) { return hn::Ge(a, b); }
inline M eq(VF a, VF b) { return hn::Eq(a, b); }
inline M ne(VF a, VF b) { return hn::Not(hn::Eq(a, b)); }
inline M lt(VI a, VI b) { return toM(hn::Lt(a, b)); }
inline M gt(VI a, VI b) { return toM(hn::Gt(a, b)); }
inline M ge(VI a, VI b) { return toM(hn::Not(hn::Lt(a, b))); }
inline M le(VI a, VI b) { return toM(hn::Not(hn::Gt(a, b))); }
inline M eq(VI a, VI b) { return toM(hn::Eq(a, b)); }
inline M ne(VI a, VI b) { return toM(hn::Not(hn::Eq(a, b))); }
/// The comparisons limited to the lanes of m: lt(m, a, b) is m & lt(a, b).
template <class V>
inline M lt(M m, V a, V b) { return hn::And(m, lt(a, b)); }
template <class V>
inline M le(M m, V a, V b) { return hn::And(m, le(a, b)); }
template <class V>
inline M ge(M m, V a, V b) { return hn::And(m, ge(a, b)); }
template <class V>
inline M eq(M m, V a, V b) { return hn::And(m, eq(a, b)); }
template <class V>
inline M ne(M m, V a, V b) { return hn::And(m, ne(a, b)); }
/// m & ~gt(a, b), m & ~lt(a, b), m & ~ge(a, b): unordered (true on NaN), as ~ is.
inline M notGt(M m, VF a, VF b) { return hn::AndNot(hn::Gt(a, b), m); }
inline M notLt(M m, VF a, VF b) { return hn::AndNot(hn::Lt(a, b), m); }
inline M notGe(M m, VF a, VF b) { return hn::AndNot(hn::Ge(a, b), m); }
/// a & ~b.
inline M andNot(M a, M b) { return hn::AndNot(b, a); }
inline M operator&(M a, M b) { return hn::And(a, b); }
inline M operator|(M a, M b) { return hn::Or(a, b); }
inline M operator^(M a, M b) { return hn::Xor(a, b); }
inline M operator~(M a) { return hn::Not(a); }
/// Lanes where i ∉ [0, n) for n ≥ 0: one unsigned compare (a negative i is a large unsigned one).
inline M outside(VI i, VI n) {
  const hn::RebindToUnsigned<DI> du;
  return toM(hn::RebindMask(DI(), hn::Not(hn::Lt(hn::BitCast(du, i), hn::BitCast(du, n)))));
}
inline bool any(M m) { return !hn::AllFalse(DF(), m); }
/// The mask with no lane set.
inline M noLanes() { return hn::FirstN(DF(), 0); }
/// The mask as bits, lane j in bit j, and back. (AVX-512 masks are k-registers whose value is
/// the bits: no trip through memory as Highway's StoreMaskBits / LoadMaskBits take — the grid's
/// lane step converts five masks a step.)
inline uint64_t bits(M m) {
#if HWY_TARGET == HWY_AVX3 || HWY_TARGET == HWY_AVX3_DL
  return uint64_t(m.raw);
#else
  uint8_t b[8] = {};
  hn::StoreMaskBits(DF(), m, b);
  uint64_t v = 0;
  std::memcpy(&v, b, sizeof v);
  return v;  // (little-endian bytes: lane j is bit j on every target Highway supports)
#endif
}
inline M fromBits(uint64_t b) {
#if HWY_TARGET == HWY_AVX3 || HWY_TARGET == HWY_AVX3_DL
  M m;
  m.raw = static_cast<decltype(m.raw)>(b);
  return m;
#else
  uint8_t bytes[8];
  std::memcpy(bytes, &b, sizeof bytes);
  return hn::LoadMaskBits(DF(), bytes);
#endif
}
/// Per-lane flags kept in memory as int32 0 / −1 (written lane by lane, read as a mask).
inline M flags(const int32_t* p) { return toM(hn::MaskFromVec(loadI(p))); }
inline void storeFlags(int32_t* p, M m) { store(p, hn::VecFromMask(DI(), toMI(m))); }

/// m ? a : b per lane.
inline VF sel(M m, VF a, VF b) { return hn::IfThenElse(m, a, b); }
inline VI sel(M m, VI a, VI b) { return hn::IfThenElse(toMI(m), a, b); }

/// std::max(a, b) = a < b ? b : a and std::min(a, b) = b < a ? b : a, bit for bit (ties, −0 and
/// NaN keep a). x86's MAXPS(x, y) is x > y ? x : y and MINPS(x, y) x < y ? x : y (the second
/// operand on ties and NaN), which Highway's x86 Max / Min are: with swapped operands they are
/// libstdc++'s rule in one instruction. Elsewhere (NEON's FMAX, the emulation) a compare and a
/// select.
inline VF vmax(VF a, VF b) {
#if HWY_ARCH_X86 && HWY_TARGET != HWY_EMU128 && HWY_TARGET != HWY_SCALAR
  return hn::Max(b, a);
#else
  return hn::IfThenElse(hn::Lt(a, b), b, a);
#endif
}
inline VF vmin(VF a, VF b) {
#if HWY_ARCH_X86 && HWY_TARGET != HWY_EMU128 && HWY_TARGET != HWY_SCALAR
  return hn::Min(b, a);
#else
  return hn::IfThenElse(hn::Lt(b, a), b, a);
#endif
}
inline VI imax(VI a, VI b) { return hn::Max(a, b); }
inline VI imin(VI a, VI b) { return hn::Min(a, b); }
inline VF vabs(VF a) { return hn::Abs(a); }
inline VF vfloor(VF a) { return hn::Floor(a); }
/// int32 lanes to float, and float lanes to int32 toward zero as static_cast does for values in
/// range. Out of range and NaN give INT32_MIN on every target, as x86's conversion does for the
/// scalar code (lanes the loops do not use hold such values; Highway's own conversion would
/// saturate on x86 and be undefined in its emulation).
inline VF toFloat(VI v) { return hn::ConvertTo(DF(), v); }
inline VI toInt(VF v) {
  const M inRange = hn::Lt(hn::Abs(v), splat(2147483648.0f));  // (false on NaN)
  return sel(inRange, hn::ConvertTo(DI(), sel(inRange, v, splat(0.0f))), splat(std::numeric_limits<int32_t>::min()));
}
inline VI asInt(VF v) { return hn::BitCast(DI(), v); }

/// table[index] per lane for a table of at most eight entries (every index in [0, 8), in every
/// lane: Highway checks it in debug builds); the table array holds at least max(8, kMaxLanes)
/// entries.
template <class D, class T>
inline hn::Vec<D> lookup8(D d, const T* table, hn::Vec<hn::RebindToSigned<D>> index) {
#if HWY_HAVE_SCALABLE
  return hn::GatherIndex(d, table, index);
#else
  if constexpr (hn::MaxLanes(D()) >= 8) {
    return hn::TableLookupLanes(hn::LoadU(d, table), hn::IndicesFromVec(d, index));
  } else {
    return hn::GatherIndex(d, table, index);
  }
#endif
}

/// field[f] lane j = float f of the 8-float record at rows[j] (j < laneCount()): one record per
/// lane read as rows and transposed in registers — 4 × 4 transposes inside 128-bit blocks
/// (32-bit, then 64-bit interleaves), then a block exchange; cheaper than eight gathers. Targets
/// whose vectors are not 4, 8 or 16 floats copy through memory. (A template: only the branch
/// of this target's width is compiled.)
template <class D = DF>
inline void transposeRecords(const float* const* rows, hn::Vec<D> field[8]) {
  const D d;
#if !HWY_HAVE_SCALABLE && HWY_TARGET != HWY_SCALAR
  const hn::Repartition<double, D> dd;
  using V = hn::Vec<D>;
  auto lo32 = [](V a, V b) { return hn::InterleaveLower(a, b); };
  auto hi32 = [&](V a, V b) { return hn::InterleaveUpper(d, a, b); };
  auto lo64 = [&](V a, V b) { return hn::BitCast(d, hn::InterleaveLower(hn::BitCast(dd, a), hn::BitCast(dd, b))); };
  auto hi64 = [&](V a, V b) { return hn::BitCast(d, hn::InterleaveUpper(dd, hn::BitCast(dd, a), hn::BitCast(dd, b))); };
  // Rows r[0..3] (and r[4..7]) → their 4 × 4 transposes inside every block: v[f] holds float
  // f (f < 4) of the four rows in each block, v[f + 4] of the next four rows.
  auto blocks4x4 = [&](const V r[8], V v[8], int groups) {
    for (int g = 0; g < groups; ++g) {
      const V u0 = lo32(r[4 * g], r[4 * g + 1]), u1 = hi32(r[4 * g], r[4 * g + 1]);
      const V u2 = lo32(r[4 * g + 2], r[4 * g + 3]), u3 = hi32(r[4 * g + 2], r[4 * g + 3]);
      v[4 * g] = lo64(u0, u2), v[4 * g + 1] = hi64(u0, u2), v[4 * g + 2] = lo64(u1, u3), v[4 * g + 3] = hi64(u1, u3);
    }
  };
  constexpr size_t N = hn::MaxLanes(D());
  if constexpr (N == 16 || N == 8) {
    // r[j]: row j (floats 0–3 and 4–7 in blocks 0 and 1) and, with 16 lanes, row j + 8 in
    // blocks 2 and 3. After the in-block transposes, v[f] (f < 4) holds float f of rows
    // 8b + 0..3 in block 2b and float f + 4 of them in block 2b + 1; v[f + 4] the same of rows
    // 8b + 4..7. A block exchange then puts each field's rows in order.
    V r[8], v[8];
    for (int j = 0; j < 8; ++j) {
      if constexpr (N == 16) {
        const hn::Half<D> dh;
        r[j] = hn::Combine(d, hn::LoadU(dh, rows[j + 8]), hn::LoadU(dh, rows[j]));
      } else {
        r[j] = hn::LoadU(d, rows[j]);
      }
    }
    blocks4x4(r, v, 2);
    for (int f = 0; f < 4; ++f) {
      field[f] = hn::OddEvenBlocks(hn::SwapAdjacentBlocks(v[f + 4]), v[f]);
      field[f + 4] = hn::OddEvenBlocks(v[f + 4], hn::SwapAdjacentBlocks(v[f]));
    }
    return;
  } else if constexpr (N == 4) {
    // Four rows, each two vectors: floats 0–3 give fields 0–3, floats 4–7 fields 4–7.
    V r[8], v[8];
    for (int j = 0; j < 4; ++j) r[j] = hn::LoadU(d, rows[j]), r[4 + j] = hn::LoadU(d, rows[j] + 4);
    blocks4x4(r, v, 2);
    for (int f = 0; f < 8; ++f) field[f] = v[f];
    return;
  }
#endif
  HWY_ALIGN float t[8][kMaxLanes];
  const size_t n = laneCount();
  for (size_t j = 0; j < n; ++j)
    for (int f = 0; f < 8; ++f) t[f][j] = rows[j][f];
  for (int f = 0; f < 8; ++f) field[f] = hn::Load(d, t[f]);
}

/// Lane refill over `kGroups` groups of lanes stepped in turn (the HSSR and SSR lane marches):
/// `fill(ln, j)` gives lane j of a group its next item (false when none is left: the lane stays
/// empty), `step(ln)` advances every live lane of a group and returns the bits of the lanes that
/// finished, `done(ln, j)` takes a finished lane's result before the lane is refilled, and
/// `refilled(ln)` runs after a group's lanes were (re)filled. With two groups each step can
/// prefetch its lanes' next records while the other group's step hides their latency. Lanes is a
/// lane state with an `int32_t ray[kMaxLanes]` member (−1: an empty lane); every group starts
/// value-initialized and empty.
template <int kGroups, class Lanes, class Fill, class Step, class Done, class Refilled>
void runLaneGroups(Lanes (&lanes)[kGroups], Fill&& fill, Step&& step, Done&& done, Refilled&& refilled) {
  const int n = int(laneCount());
  int live = 0;
  for (Lanes& ln : lanes) {
    ln = Lanes{};
    for (int32_t& r : ln.ray) r = -1;
    for (int j = 0; j < n; ++j) live += fill(ln, j);
    refilled(ln);
  }
  while (live > 0) {
    uint64_t finished[kGroups];
    for (int g = 0; g < kGroups; ++g) finished[g] = step(lanes[g]);
    for (int g = 0; g < kGroups; ++g) {
      if (!finished[g]) continue;
      for (uint64_t m = finished[g]; m; m &= m - 1) {
        const int j = std::countr_zero(m);
        done(lanes[g], j);
        live += int(fill(lanes[g], j)) - 1;
      }
      refilled(lanes[g]);
    }
  }
}

}  // namespace lt::HWY_NAMESPACE::lanes
HWY_AFTER_NAMESPACE();

#endif  // per-target include guard
