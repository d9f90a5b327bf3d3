#pragma once
// Internal to libice: sorting records keyed first by a vertex id (half-edges, faces by their
// smallest corner) without a comparison sort over all of them. A counting sort on the vertex puts
// each vertex's handful of records together in one linear, cache-friendly pass; a small stable
// sort orders each bucket. At 1.6M vertices this is several times faster than std::sort on the
// records, whose comparisons spend their time in random key lookups.
#include <algorithm>
#include <cstddef>
#include <vector>

#include "ice/mesh.h"
#include "run_tasks.h"

namespace ice::detail {

/// The permutation of records 0..count−1 sorted by (vertex_of(r), then `less` within a vertex),
/// stable (equal records keep their order). vertex_of(r) must lie in [0, vertices). The buckets are
/// ordered on `threads` threads (`less` is then called concurrently).
template <class VertexOf, class Less>
std::vector<Index> order_by_vertex(std::size_t count, Index vertices, VertexOf&& vertex_of, Less&& less, int threads = 1) {
  std::vector<std::size_t> start(static_cast<std::size_t>(vertices) + 1, 0);
  for (std::size_t r = 0; r < count; ++r) ++start[static_cast<std::size_t>(vertex_of(static_cast<Index>(r))) + 1];
  for (std::size_t v = 0; v < static_cast<std::size_t>(vertices); ++v) start[v + 1] += start[v];
  std::vector<Index> order(count);
  {
    std::vector<std::size_t> fill(start.begin(), start.end() - 1);
    for (std::size_t r = 0; r < count; ++r) order[fill[vertex_of(static_cast<Index>(r))]++] = static_cast<Index>(r);
  }
  run_ranges(threads, static_cast<std::size_t>(vertices), [&](std::size_t first, std::size_t last) {
    for (std::size_t v = first; v < last; ++v) {
      const std::size_t begin = start[v], end = start[v + 1];
      if (end - begin > 32) {  // a vertex of very high valence: no quadratic insertion sort
        std::stable_sort(order.begin() + static_cast<std::ptrdiff_t>(begin), order.begin() + static_cast<std::ptrdiff_t>(end), less);
        continue;
      }
      for (std::size_t i = begin + 1; i < end; ++i) {
        const Index r = order[i];
        std::size_t j = i;
        for (; j > begin && less(r, order[j - 1]); --j) order[j] = order[j - 1];
        order[j] = r;
      }
    }
  });
  return order;
}

/// Sorts `records` in place by (vertex_of(record), then `less` within a vertex), stably, with the
/// same counting sort as order_by_vertex but moving the records themselves (one scattering pass
/// instead of an index order and a gathering pass: half the random memory accesses). The buckets are
/// ordered on `threads` threads.
template <class Record, class VertexOf, class Less>
void sort_by_vertex(std::vector<Record>& records, Index vertices, VertexOf&& vertex_of, Less&& less, int threads = 1) {
  std::vector<std::size_t> start(static_cast<std::size_t>(vertices) + 1, 0);
  for (const Record& record : records) ++start[static_cast<std::size_t>(vertex_of(record)) + 1];
  for (std::size_t v = 0; v < static_cast<std::size_t>(vertices); ++v) start[v + 1] += start[v];
  std::vector<Record> sorted(records.size());
  {
    std::vector<std::size_t> fill(start.begin(), start.end() - 1);
    for (const Record& record : records) sorted[fill[vertex_of(record)]++] = record;
  }
  run_ranges(threads, static_cast<std::size_t>(vertices), [&](std::size_t first, std::size_t last) {
    for (std::size_t v = first; v < last; ++v) {
      const std::size_t begin = start[v], end = start[v + 1];
      if (end - begin < 2) continue;  // nothing to order (and no iterator may step past an empty bucket)
      if (end - begin > 32) {
        std::stable_sort(sorted.begin() + static_cast<std::ptrdiff_t>(begin), sorted.begin() + static_cast<std::ptrdiff_t>(end), less);
        continue;
      }
      for (std::size_t i = begin + 1; i < end; ++i) {
        Record record = sorted[i];
        std::size_t j = i;
        for (; j > begin && less(record, sorted[j - 1]); --j) sorted[j] = sorted[j - 1];
        sorted[j] = record;
      }
    }
  });
  records.swap(sorted);
}

}  // namespace ice::detail
