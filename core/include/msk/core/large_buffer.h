#pragma once
/// An allocator for buffers of image size that asks the kernel for transparent huge pages.
///
/// A fresh buffer costs a page fault per 4 KiB page on first touch. On the virtual machines this project runs on that
/// is about 3 ms per MiB (17 ms for one 6 MiB image buffer, measured), more than smoothing the image. Buffers of at
/// least kHugeFrom bytes are therefore mapped on their own, 2 MiB aligned, with madvise(MADV_HUGEPAGE): one fault per
/// 2 MiB where the kernel's transparent huge pages are "always" or "madvise" (0.2–0.5 ms for the same buffer), and the
/// ordinary pages otherwise. glibc's own switch for this (the glibc.malloc.hugetlb tunable) is read from the
/// environment at start-up only, so a program cannot turn it on for itself. Smaller buffers come from std::allocator.
#include <cstddef>
#include <memory>
#include <new>
#include <vector>

// Under AddressSanitizer or MemorySanitizer every buffer comes from std::allocator, exactly sized, so that the
// sanitizer still sees its bounds.
#if defined(__SANITIZE_ADDRESS__)
#define MSK_MAP_LARGE_BUFFERS 0
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(memory_sanitizer)
#define MSK_MAP_LARGE_BUFFERS 0
#endif
#endif
#ifndef MSK_MAP_LARGE_BUFFERS
#define MSK_MAP_LARGE_BUFFERS 1
#endif

namespace msk {

namespace detail {
/// Maps `bytes` (a multiple of kHugePage) 2 MiB-aligned with huge pages advised; throws std::bad_alloc on failure.
void* mapLargeBuffer(size_t bytes);
/// Unmaps a buffer of mapLargeBuffer().
void unmapLargeBuffer(void* p, size_t bytes) noexcept;
constexpr size_t kHugePage = size_t{2} << 20;
/// Buffers from 1 MiB up are mapped (none under a sanitizer).
constexpr size_t kHugeFrom = MSK_MAP_LARGE_BUFFERS ? size_t{1} << 20 : static_cast<size_t>(-1);
}  // namespace detail

/// std::allocator for small buffers; huge-page mappings from detail::kHugeFrom bytes up. Stateless: any two compare
/// equal.
template <typename T>
struct LargeBufferAllocator {
  using value_type = T;

  LargeBufferAllocator() = default;
  template <typename U>
  LargeBufferAllocator(const LargeBufferAllocator<U>&) noexcept {}

  T* allocate(size_t n) {
    if (n > static_cast<size_t>(-1) / sizeof(T)) throw std::bad_alloc();
    const size_t bytes = n * sizeof(T);
    if (bytes < detail::kHugeFrom) return std::allocator<T>().allocate(n);
    return static_cast<T*>(detail::mapLargeBuffer(rounded(bytes)));
  }
  void deallocate(T* p, size_t n) noexcept {
    const size_t bytes = n * sizeof(T);
    if (bytes < detail::kHugeFrom)
      std::allocator<T>().deallocate(p, n);
    else
      detail::unmapLargeBuffer(p, rounded(bytes));
  }

 private:
  static size_t rounded(size_t bytes) {
    return (bytes + detail::kHugePage - 1) / detail::kHugePage * detail::kHugePage;
  }
};

template <typename T, typename U>
bool operator==(const LargeBufferAllocator<T>&, const LargeBufferAllocator<U>&) noexcept {
  return true;
}
template <typename T, typename U>
bool operator!=(const LargeBufferAllocator<T>&, const LargeBufferAllocator<U>&) noexcept {
  return false;
}

/// A std::vector whose storage, from 1 MiB up, is a huge-page mapping.
template <typename T>
using LargeVector = std::vector<T, LargeBufferAllocator<T>>;

}  // namespace msk
