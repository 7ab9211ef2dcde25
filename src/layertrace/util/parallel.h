// Parallel loops: tbb::parallel_for, made visible to ThreadSanitizer.
//
// Debian's libtbb is not instrumented, so TSan cannot see that a worker runs a loop body only
// after the calling thread submitted it, nor that the caller continues only after every body
// finished: everything written before a loop and read inside it looks like a race. In a TSan
// build these wrappers state those two edges (release before the loop, acquire at each body's
// start; release at each body's end, acquire after the loop). Bodies get no edge between each
// other, so a race between two iterations is still reported. Elsewhere they are tbb::parallel_for.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#if defined(__SANITIZE_THREAD__)
#define LAYERTRACE_TSAN_ANNOTATE 1
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer)
#define LAYERTRACE_TSAN_ANNOTATE 1
#endif
#endif

#ifdef LAYERTRACE_TSAN_ANNOTATE
extern "C" void __tsan_acquire(void* addr);
extern "C" void __tsan_release(void* addr);
#endif

namespace lt {

namespace detail {
#ifdef LAYERTRACE_TSAN_ANNOTATE
/// The two edges, on global addresses: a body must acquire before it reads anything the caller
/// wrote — even the references its closure captured.
inline char gLoopBefore = 0, gLoopAfter = 0;
inline void loopStart() { __tsan_release(&gLoopBefore); }
inline void loopEnd() { __tsan_acquire(&gLoopAfter); }
inline void bodyStart() { __tsan_acquire(&gLoopBefore); }
inline void bodyEnd() { __tsan_release(&gLoopAfter); }
#else
inline void loopStart() {}
inline void loopEnd() {}
inline void bodyStart() {}
inline void bodyEnd() {}
#endif
}  // namespace detail

/// tbb::parallel_for over a range (blocked_range and friends).
template <class Range, class Body>
void parallelFor(const Range& range, const Body& body) {
  detail::loopStart();
  tbb::parallel_for(range, [&](const Range& r) {
    detail::bodyStart();
    body(r);
    detail::bodyEnd();
  });
  detail::loopEnd();
}

/// tbb::parallel_for over the indices [first, last).
template <class Index, class Body>
void parallelFor(Index first, Index last, const Body& body) {
  detail::loopStart();
  tbb::parallel_for(first, last, [&](Index i) {
    detail::bodyStart();
    body(i);
    detail::bodyEnd();
  });
  detail::loopEnd();
}

/// Exclusive prefix sum in parallel: out[i] = min(Σ_{j<i} in[j], cap) for i in [0, n); returns
/// the whole sum (not capped). `out` may be `in` (each element is read before it is written).
/// Two passes over blocks — their sums in parallel, a short serial scan over the block sums, then
/// each block's own scan in parallel — with the serial loop's result, bit for bit.
template <class In, class Out>
uint64_t parallelExclusiveScan(const In* in, Out* out, size_t n, uint64_t cap) {
  constexpr size_t kBlock = size_t(1) << 16;
  const size_t blocks = (n + kBlock - 1) / kBlock;
  std::vector<uint64_t> start(blocks + 1, 0);
  parallelFor(size_t(0), blocks, [&](size_t b) {
    uint64_t sum = 0;
    for (size_t i = b * kBlock, end = std::min(n, (b + 1) * kBlock); i < end; ++i) sum += uint64_t(in[i]);
    start[b + 1] = sum;
  });
  for (size_t b = 0; b < blocks; ++b) start[b + 1] += start[b];
  parallelFor(size_t(0), blocks, [&](size_t b) {
    uint64_t total = start[b];
    for (size_t i = b * kBlock, end = std::min(n, (b + 1) * kBlock); i < end; ++i) {
      const uint64_t v = uint64_t(in[i]);
      out[i] = Out(std::min(total, cap));
      total += v;
    }
  });
  return start[blocks];
}

}  // namespace lt
