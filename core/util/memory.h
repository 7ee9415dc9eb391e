#pragma once
// Memory for frame-rate work: process-wide allocator tuning, and cache-line aligned buffers for
// the vectorized loops (CacheLineVector).
//
// Every frame allocates and frees a few image-sized buffers (~300 KB at 320x240). With glibc's
// defaults the freed top of the heap is returned to the kernel and the next frame faults the
// pages back in, zero-filled: measured at 20% of feature extraction time. Keeping freed memory
// (it is reused by the very next frame) removes that cost. Malloc arenas are capped at one per
// core, so a server's many session threads do not each keep their own freed memory.

#include <cstddef>
#include <new>
#include <vector>

namespace visloc {

constexpr size_t kCacheLineBytes = 64;

// An allocator whose blocks start on a cache line. malloc's blocks are 16-byte aligned, so where
// a buffer fell decided whether every 64-byte (AVX-512) load and store of a hot loop split two
// cache lines: detection on the same image ran up to 9% slower or faster as other allocations
// moved it.
template <typename T>
struct CacheLineAllocator {
  using value_type = T;
  CacheLineAllocator() = default;
  template <typename U>
  CacheLineAllocator(const CacheLineAllocator<U>&) {}
  T* allocate(size_t n) {
    return static_cast<T*>(::operator new (n * sizeof(T), std::align_val_t{kCacheLineBytes}));
  }
  void deallocate(T* p, size_t) { ::operator delete (p, std::align_val_t{kCacheLineBytes}); }
  template <typename U>
  bool operator==(const CacheLineAllocator<U>&) const {
    return true;
  }
  template <typename U>
  bool operator!=(const CacheLineAllocator<U>&) const {
    return false;
  }
};

// A vector for a hot loop's buffers: its first element on a cache line.
template <typename T>
using CacheLineVector = std::vector<T, CacheLineAllocator<T>>;

// Call once at program start, before threads are created.
void KeepFreedMemoryForReuse();

}  // namespace visloc
