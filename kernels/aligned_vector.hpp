// std::vector on 64-byte (cache line, AVX-512 vector) boundaries: a vector load at a multiple of
// the vector width from its start never straddles two cache lines.
#pragma once

#include <cstddef>
#include <new>
#include <vector>

namespace stampede::kernels {

inline constexpr std::size_t kVectorAlignment = 64;

template <class T>
struct CacheAlignedAllocator {
  using value_type = T;
  CacheAlignedAllocator() = default;
  template <class U>
  CacheAlignedAllocator(const CacheAlignedAllocator<U>&) noexcept {}
  T* allocate(std::size_t n) {
    return static_cast<T*>(::operator new(n * sizeof(T), std::align_val_t(kVectorAlignment)));
  }
  void deallocate(T* p, std::size_t) noexcept { ::operator delete(p, std::align_val_t(kVectorAlignment)); }
  template <class U>
  bool operator==(const CacheAlignedAllocator<U>&) const noexcept {
    return true;
  }
};

template <class T>
using AlignedVector = std::vector<T, CacheAlignedAllocator<T>>;

// n rounded up to whole 64-byte lines of T: a stride that keeps every row of a packed array aligned.
template <class T>
constexpr std::size_t aligned_stride(std::size_t n) {
  constexpr std::size_t per_line = kVectorAlignment / sizeof(T);
  return (n + per_line - 1) / per_line * per_line;
}

}  // namespace stampede::kernels
