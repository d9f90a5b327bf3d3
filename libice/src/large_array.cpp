#include "ice/large_array.h"

#include <climits>
#include <cstdlib>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include "ice/huge_pages.h"

namespace ice::detail {

void* allocate_large(std::size_t bytes) {
  constexpr std::size_t kHugePage = std::size_t{1} << 21;
  const std::size_t rounded = (bytes + kHugePage - 1) / kHugePage * kHugePage;  // aligned_alloc needs a multiple
  void* pointer = std::aligned_alloc(kHugePage, rounded);
  if (pointer == nullptr) throw std::bad_alloc();
  // Before the first touch, so that the page faults allocate huge pages directly. Advice only: a
  // refusal (no THP support, or disabled) leaves ordinary pages.
  advise_huge_pages(pointer, rounded);
  return pointer;
}

void deallocate_large(void* pointer) noexcept { std::free(pointer); }

}  // namespace ice::detail

namespace ice {

bool keep_freed_memory_for_reuse() noexcept {
#if defined(__GLIBC__)
  // mallopt returns 1 on success (AddressSanitizer's replacement returns 0).
  const bool heap_only = mallopt(M_MMAP_MAX, 0) == 1;
  const bool no_trim = mallopt(M_TRIM_THRESHOLD, INT_MAX) == 1;
  return heap_only && no_trim;
#else
  return false;
#endif
}

}  // namespace ice
