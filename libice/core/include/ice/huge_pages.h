#pragma once
/// \file huge_pages.h
/// Advice to the kernel that a large buffer be backed by transparent huge pages (Linux
/// madvise(MADV_HUGEPAGE)); nothing elsewhere, or when refused. Given before the buffer's first
/// touch, its page faults then allocate 2 MiB pages directly: a few hundred faults instead of a
/// few hundred thousand for a GB-sized result (docs/measurements.md, "The eigenbasis through the proxy").
#include <cstddef>
#include <cstdint>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace ice {

/// Advises the whole 2 MiB pages inside [data, data + bytes) (only those: madvise needs aligned
/// ranges, and the rest of a partly covered page may belong to other allocations).
inline void advise_huge_pages(void* data, std::size_t bytes) {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  constexpr std::uintptr_t kHugePage = std::uintptr_t{1} << 21;
  const auto begin = reinterpret_cast<std::uintptr_t>(data);
  const std::uintptr_t first = (begin + kHugePage - 1) / kHugePage * kHugePage;
  const std::uintptr_t last = (begin + bytes) / kHugePage * kHugePage;
  if (last > first) (void)madvise(reinterpret_cast<void*>(first), last - first, MADV_HUGEPAGE);
#else
  (void)data;
  (void)bytes;
#endif
}

}  // namespace ice
