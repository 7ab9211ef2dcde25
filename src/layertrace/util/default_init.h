// An allocator for large pools that are written before they are read — as a GPU buffer would
// be: it default-initialises (leaves trivial types uninitialised) and backs large blocks with
// transparent huge pages where the kernel offers them.
#pragma once

#include <cstddef>
#include <cstdlib>
#include <memory>
#include <new>
#include <vector>

#include <sys/mman.h>

namespace lt {

/// Blocks of at least this many bytes are 2 MiB aligned and advised as huge pages (Linux THP in
/// "madvise" mode, Debian's default): first-touch page faults then come 512× less often, which
/// in a VM were a fifth of a frame's time (perf: the kernel's fault path while the rasterizer
/// and the quad-tree build first wrote their pools).
inline constexpr size_t kHugePageBytes = size_t(2) << 20;

template <typename T>
class PoolAllocator {
 public:
  using value_type = T;
  PoolAllocator() = default;
  template <typename U>
  PoolAllocator(const PoolAllocator<U>&) noexcept {}

  T* allocate(size_t n) {
    if (n > size_t(-1) / sizeof(T)) throw std::bad_array_new_length();
    const size_t bytes = n * sizeof(T);
    if (bytes < 2 * kHugePageBytes) return static_cast<T*>(::operator new(bytes, std::align_val_t(alignof(T))));
    const size_t rounded = (bytes + kHugePageBytes - 1) / kHugePageBytes * kHugePageBytes;
    void* p = std::aligned_alloc(kHugePageBytes, rounded);
    if (!p) throw std::bad_alloc();
    madvise(p, rounded, MADV_HUGEPAGE);  // advice only: failure leaves normal pages
    return static_cast<T*>(p);
  }
  void deallocate(T* p, size_t n) noexcept {
    if (n * sizeof(T) < 2 * kHugePageBytes) ::operator delete(p, std::align_val_t(alignof(T)));
    else std::free(p);
  }
  /// Default-initialise: no zeroing pass over memory the owner is about to write.
  template <typename U>
  void construct(U* p) noexcept(std::is_nothrow_default_constructible_v<U>) {
    ::new (static_cast<void*>(p)) U;
  }
  template <typename U, typename... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
  template <typename U>
  bool operator==(const PoolAllocator<U>&) const noexcept {
    return true;
  }
};

template <typename T>
using PoolVector = std::vector<T, PoolAllocator<T>>;

}  // namespace lt
