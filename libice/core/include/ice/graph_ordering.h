#pragma once
/// \file graph_ordering.h
/// Reverse Cuthill–McKee ordering of a graph given in compressed adjacency form (header-only, so
/// that libfem orders matrix graphs with it without linking libice).
///
/// The graph has n vertices; the neighbours of v are adjacency[offsets[v] .. offsets[v+1]) (it must
/// be symmetric: u lists v iff v lists u; self-loops and repeated neighbours are allowed and ignored).
/// The result `order` has order[new] = old and is a permutation of 0..n−1: each connected component
/// numbered contiguously, breadth first from a pseudo-peripheral vertex (one step of George–Liu's
/// search: a low-degree vertex farthest from a minimum-degree one), the new neighbours of each vertex in increasing (degree, index), and the whole
/// numbering reversed. Deterministic. O(nnz + n log n).
///
/// Why: every neighbour of a vertex then lies within the band of the breadth-first levels around it
/// (on a surface mesh of n vertices, typically a few √n), so per-vertex arrays read around a vertex
/// hit the caches, and contiguous index ranges are compact regions of the mesh.
#include <algorithm>
#include <cstddef>
#include <vector>

namespace ice {

namespace detail {

// Breadth-first search from `root` over vertices with mark != stamp, marking them `stamp` and
// appending them to `out`; new neighbours sorted by (degree, index) when `sorted` (the probes only
// need the levels). Returns the number of levels and the start of the last level in `out`.
template <class Offset, class Neighbour>
int breadth_first(const Offset* offsets, const Neighbour* adjacency, const std::vector<int>& degree, int root,
                  std::vector<int>& mark, int stamp, bool sorted, std::vector<int>& out, std::size_t* last_level_begin) {
  std::size_t level_begin = out.size();
  out.push_back(root);
  mark[static_cast<std::size_t>(root)] = stamp;
  int levels = 1;
  std::vector<int> neighbours;
  std::size_t head = level_begin, level_end = out.size();
  const auto by_degree = [&](int a, int b) {
    const int da = degree[static_cast<std::size_t>(a)], db = degree[static_cast<std::size_t>(b)];
    return da != db ? da < db : a < b;
  };
  while (true) {
    for (; head < level_end; ++head) {
      // The queue is known ahead: request the rows and the marks of the vertices a few places on
      // (the input numbering may scatter them), so that the misses overlap.
      if (head + 8 < out.size()) __builtin_prefetch(&offsets[out[head + 8]]);
      if (head + 4 < out.size()) __builtin_prefetch(&adjacency[offsets[out[head + 4]]]);
      if (head + 2 < out.size()) {
        const int w = out[head + 2];
        for (auto p = offsets[w]; p < offsets[w + 1]; ++p) __builtin_prefetch(&mark[static_cast<std::size_t>(adjacency[p])]);
      }
      const int v = out[head];
      neighbours.clear();
      for (auto p = offsets[v]; p < offsets[v + 1]; ++p) {
        const int u = static_cast<int>(adjacency[p]);
        if (mark[static_cast<std::size_t>(u)] == stamp) continue;
        mark[static_cast<std::size_t>(u)] = stamp;
        neighbours.push_back(u);
      }
      if (sorted) std::sort(neighbours.begin(), neighbours.end(), by_degree);
      out.insert(out.end(), neighbours.begin(), neighbours.end());
    }
    if (out.size() == level_end) break;  // no new level
    level_begin = level_end;
    level_end = out.size();
    ++levels;
  }
  *last_level_begin = level_begin;
  return levels;
}

}  // namespace detail

template <class Offset, class Neighbour>
std::vector<int> reverse_cuthill_mckee(int n, const Offset* offsets, const Neighbour* adjacency) {
  // Degrees without self-loops (repeats, as in a face list's adjacency, count twice: they only
  // break ties among neighbours).
  std::vector<int> degree(static_cast<std::size_t>(n), 0);
  for (int v = 0; v < n; ++v)
    for (auto p = offsets[v]; p < offsets[v + 1]; ++p)
      if (static_cast<int>(adjacency[p]) != v) ++degree[static_cast<std::size_t>(v)];
  // Component roots are tried in increasing degree (then index): a counting sort on the degree
  // (a comparison sort of all vertices took a large share of the ordering's time on large meshes;
  // docs/measurements.md, "Graph ordering").
  int max_degree = 0;
  for (int v = 0; v < n; ++v) max_degree = std::max(max_degree, degree[static_cast<std::size_t>(v)]);
  std::vector<int> by_degree(static_cast<std::size_t>(n));
  {
    std::vector<std::size_t> start(static_cast<std::size_t>(max_degree) + 2, 0);
    for (int v = 0; v < n; ++v) ++start[static_cast<std::size_t>(degree[static_cast<std::size_t>(v)]) + 1];
    for (std::size_t d = 1; d < start.size(); ++d) start[d] += start[d - 1];
    for (int v = 0; v < n; ++v) by_degree[start[static_cast<std::size_t>(degree[static_cast<std::size_t>(v)])]++] = v;
  }

  std::vector<int> order, probe;
  order.reserve(static_cast<std::size_t>(n));
  std::vector<int> mark(static_cast<std::size_t>(n), 0);  // 1: numbered; probes use stamps ≥ 2
  int stamp = 1;
  for (int candidate : by_degree) {
    if (mark[static_cast<std::size_t>(candidate)] == 1) continue;
    // George–Liu: move the root to a low-degree vertex of the last level while the eccentricity
    // grows. One move only: each probe is a full pass over the component, and more probes gave a
    // barely narrower band for much more time (docs/measurements.md, "Graph ordering").
    int root = candidate, levels = 0;
    for (int attempt = 0; attempt < 1; ++attempt) {
      probe.clear();
      std::size_t last_begin = 0;
      ++stamp;
      const int probe_levels = detail::breadth_first(offsets, adjacency, degree, root, mark, stamp, false, probe, &last_begin);
      for (int v : probe) mark[static_cast<std::size_t>(v)] = 0;  // unnumbered again
      if (probe_levels <= levels) break;
      levels = probe_levels;
      int best = probe[last_begin];
      for (std::size_t i = last_begin; i < probe.size(); ++i)
        if (degree[static_cast<std::size_t>(probe[i])] < degree[static_cast<std::size_t>(best)]) best = probe[i];
      if (best == root) break;
      root = best;
    }
    std::size_t unused = 0;
    detail::breadth_first(offsets, adjacency, degree, root, mark, 1, true, order, &unused);
  }
  std::reverse(order.begin(), order.end());
  return order;
}

}  // namespace ice
