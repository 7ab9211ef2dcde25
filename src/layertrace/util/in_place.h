// Writing a function's result straight into an array element.
//
// `out[i] = make(...)` for a struct returned by value makes GCC build the result in a stack
// temporary with scalar stores and copy it with 16-byte loads, which the CPU cannot forward
// from those stores: a store-forwarding stall (~15 cycles) per element. In the ray batches that
// was a third of the plain Embree batch's own samples and most of HssrTracer::traceBatch's
// (measured with perf annotate). Constructing the element from the prvalue instead (C++17
// guaranteed elision) lets the callee write the element itself. Same bytes either way.
#pragma once

#include <memory>
#include <new>
#include <type_traits>
#include <utility>

namespace lt {

/// dst = make(), with make()'s result constructed in dst's storage. For trivially destructible,
/// trivially copyable T (the old value needs no destruction and nothing refers into it).
template <class T, class Make>
inline void assignInPlace(T& dst, Make&& make) {
  static_assert(std::is_trivially_destructible_v<T> && std::is_trivially_copyable_v<T>);
  ::new (static_cast<void*>(std::addressof(dst))) T(std::forward<Make>(make)());
}

}  // namespace lt
