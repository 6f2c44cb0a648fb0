#include "msk/core/large_buffer.h"

#include <cstdint>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace msk::detail {

#if defined(__linux__)

void* mapLargeBuffer(size_t bytes) {
  // Over-map by one huge page, then unmap the head and tail beyond the 2 MiB-aligned range, which is all that stays.
  const size_t span = bytes + kHugePage;
  void* raw = mmap(nullptr, span, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (raw == MAP_FAILED) throw std::bad_alloc();
  const uintptr_t start = reinterpret_cast<uintptr_t>(raw);
  const uintptr_t aligned = (start + kHugePage - 1) / kHugePage * kHugePage;
  if (aligned > start) munmap(raw, aligned - start);
  const size_t tail = start + span - (aligned + bytes);
  if (tail > 0) munmap(reinterpret_cast<void*>(aligned + bytes), tail);
  void* p = reinterpret_cast<void*>(aligned);
#if defined(MADV_HUGEPAGE)
  madvise(p, bytes, MADV_HUGEPAGE);  // advice only: without transparent huge pages the ordinary pages serve
#endif
  return p;
}

void unmapLargeBuffer(void* p, size_t bytes) noexcept { munmap(p, bytes); }

#else

void* mapLargeBuffer(size_t bytes) { return ::operator new(bytes, std::align_val_t(kHugePage)); }

void unmapLargeBuffer(void* p, size_t) noexcept { ::operator delete(p, std::align_val_t(kHugePage)); }

#endif

}  // namespace msk::detail
