#pragma once
/// \file large_array.h
/// ice::LargeArray<T>: a std::vector whose large buffers (2 MiB and more) are aligned to 2 MiB and
/// offered to the kernel for transparent huge pages (Linux madvise(MADV_HUGEPAGE); elsewhere, or
/// when refused, plain pages). Smaller buffers come from std::allocator.
///
/// Why: mesh coarsening follows its cost order, not memory order, so on a million-vertex mesh
/// almost every removal reads half-edge and vertex records that are neither in the caches nor in
/// the TLB. With 4 KiB pages each such read also walks the page table; 2 MiB pages cover a
/// million-vertex triangulation with a few hundred TLB entries at most. Measured faster than plain
/// pages on a million-vertex coarsening, as fast as glibc's own huge-page mode for every allocation,
/// at nearly the same peak memory (docs/measurements.md, "Huge pages for large arrays"). Most Linux
/// systems default to huge pages only where asked
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
/// page fault and the kernel's zeroing per page on first touch, every time. On a million-vertex
/// multigrid solve page faults took a large share of the CPU time, and this setting made the
/// hierarchy, the setup and solve, and the fine operators' assembly measurably faster; raising only
/// the mmap threshold (to its 32 MiB cap) gained nothing: the churn is in the larger blocks
/// (docs/measurements.md, "Keeping freed memory for reuse").
///
/// Cost: resident memory no longer shrinks when arrays are freed, and the heap's fragmentation
/// counts (peak memory grows; same section). Hence the policy: the solving tools
/// (poisson-coarse, geodesic-coarse, vector-coarse, ice-report) and the benchmarks call this at
/// start (one process per job); ice-coarsen does not (it would gain little and raise its memory per
/// input vertex; same section); the libraries never call it themselves, since a
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
