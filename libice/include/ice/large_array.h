#pragma once
/// \file large_array.h
/// ice::LargeArray<T>: a std::vector whose large buffers (2 MiB and more) are aligned to 2 MiB and
/// offered to the kernel for transparent huge pages (Linux madvise(MADV_HUGEPAGE); elsewhere, or
/// when refused, plain pages). Smaller buffers come from std::allocator.
///
/// Why: mesh coarsening follows its cost order, not memory order, so on a million-vertex mesh
/// almost every removal reads half-edge and vertex records that are neither in the caches nor in
/// the TLB. With 4 KiB pages each such read also walks the page table; 2 MiB pages cover the
/// ~270 MB of a 1.15M-vertex triangulation with ~135 TLB entries. Measured (fertility Loop ×4,
/// 1.15M → 10k vertices, three interleaved runs each): 19.8–20.8 s against 21.2–26.0 s with plain
/// pages (median 1.07x), as fast as glibc's own huge-page mode for every allocation; peak RSS
/// 518 MB vs 507 MB. Most Linux systems default to huge pages only where asked
/// (/sys/kernel/mm/transparent_hugepage/enabled = madvise), hence the request.
#include <cstddef>
#include <memory>
#include <new>
#include <utility>
#include <vector>

namespace ice {
namespace detail {

constexpr std::size_t kLargeArrayBytes = std::size_t{1} << 21;
/// 2 MiB-aligned storage for at least `bytes` bytes, offered for huge pages. Throws std::bad_alloc.
void* allocate_large(std::size_t bytes);
void deallocate_large(void* pointer) noexcept;

}  // namespace detail

/// Asks this process's malloc (glibc's) to serve every block from its heap and to keep the memory
/// freed there for later allocations instead of handing it back to the kernel (mallopt: M_MMAP_MAX
/// = 0, M_TRIM_THRESHOLD = INT_MAX). Returns whether the allocator took both settings: false off
/// glibc and under AddressSanitizer, which replaces malloc (nothing changes then). True means glibc's
/// malloc took them; it says nothing about an allocator preloaded in its place (jemalloc, mimalloc),
/// which ignores them.
///
/// Why: a solve pipeline allocates and frees arrays of tens to hundreds of MB one after another
/// (each multigrid level's triangulation, numbering, sparse products). glibc maps every block above
/// its mmap threshold (at most 32 MiB) afresh and unmaps it when freed, so each such array pays a
/// page fault and the kernel's zeroing per page on first touch, every time. Measured at 1,657,090
/// vertices (`poisson-coarse --solver multigrid`, fandisk Loop-subdivided 4 times, the previous
/// version and this one alternated, three runs each): page faults were 15 % of the process's CPU
/// samples; with this setting the hierarchy took 4.48–4.81 s instead of 5.12–5.19 s and setup +
/// solve 6.25–6.87 s instead of 7.18–7.36 s, the fine operators' assembly 0.94–1.01 s instead of
/// 1.19–1.20 s. Raising only the mmap threshold (to its 32 MiB cap) gained nothing: the churn is in
/// the larger blocks.
///
/// Cost: resident memory no longer shrinks when arrays are freed, and the heap's fragmentation
/// counts (peak RSS 1,569 → 1,773–1,778 MB in those runs). Hence the policy: the solving tools
/// (poisson-coarse, geodesic-coarse, vector-coarse, ice-report) and the benchmarks call this at
/// start (one process per job); ice-coarsen does not (at 1.58M vertices it would gain 5 % and pass
/// 500 bytes per input vertex: 494 → 517); the libraries never call it themselves, since a
/// long-lived process (Python, a server) would keep its largest heap for good. Call it before the
/// first large allocation; blocks mapped earlier stay mapped.
bool keep_freed_memory_for_reuse() noexcept;

template <class T>
struct LargeArrayAllocator {
  using value_type = T;
  LargeArrayAllocator() noexcept = default;
  template <class U>
  LargeArrayAllocator(const LargeArrayAllocator<U>&) noexcept {}
  T* allocate(std::size_t n) {
    if (n * sizeof(T) < detail::kLargeArrayBytes) return std::allocator<T>().allocate(n);
    return static_cast<T*>(detail::allocate_large(n * sizeof(T)));
  }
  void deallocate(T* pointer, std::size_t n) noexcept {
    if (n * sizeof(T) < detail::kLargeArrayBytes)
      std::allocator<T>().deallocate(pointer, n);
    else
      detail::deallocate_large(pointer);
  }
  /// resize(n) and LargeArray(n) default-initialise: trivial records are left unwritten (no page
  /// is touched), so that the caller can fill a large array on several threads, each first touch
  /// (the kernel zeroing a page) on the thread that fills it. Give a value to have it filled.
  template <class U>
  void construct(U* pointer) noexcept(noexcept(::new (static_cast<void*>(pointer)) U)) {
    ::new (static_cast<void*>(pointer)) U;
  }
  template <class U, class... Args>
  void construct(U* pointer, Args&&... args) {
    ::new (static_cast<void*>(pointer)) U(std::forward<Args>(args)...);
  }
  template <class U>
  bool operator==(const LargeArrayAllocator<U>&) const noexcept { return true; }
  template <class U>
  bool operator!=(const LargeArrayAllocator<U>&) const noexcept { return false; }
};

template <class T>
using LargeArray = std::vector<T, LargeArrayAllocator<T>>;

}  // namespace ice
