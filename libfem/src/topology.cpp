#include "fem/topology.h"

#include <algorithm>
#include <cstdint>
#include <string>
#include <utility>

namespace fem {

std::vector<Index> boundary_vertices(const ice::Faces& F) {
  // Around each vertex v, every face (v, w, x) lists w and x: an edge (v, w) is in as many faces as w
  // is listed around v, so a neighbour listed once is across a boundary edge. Per-vertex lists (a
  // counting sort into CSR, then a sort of each short list) instead of one sort of all edge keys:
  // 0.54 s → 0.1 s at 3.2M faces.
  if (F.rows() == 0) return {};
  const auto n = static_cast<std::size_t>(F.maxCoeff()) + 1;
  std::vector<Index> start(n + 1, 0);
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) start[static_cast<std::size_t>(F(f, k)) + 1] += 2;
  for (std::size_t v = 0; v < n; ++v) start[v + 1] += start[v];
  std::vector<Index> listed(static_cast<std::size_t>(start[n]));
  std::vector<Index> fill(start.begin(), start.end() - 1);
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      // One entry per side at v: a loop side v → v of a Δ-complex is listed once, as a next corner.
      const auto v = static_cast<std::size_t>(F(f, k));
      const Index next = F(f, (k + 1) % 3), previous = F(f, (k + 2) % 3);
      listed[static_cast<std::size_t>(fill[v]++)] = next;
      if (static_cast<std::size_t>(previous) != v) listed[static_cast<std::size_t>(fill[v]++)] = previous;
    }
  std::vector<Index> vertices;
  for (std::size_t v = 0; v < n; ++v) {
    const auto begin = listed.begin() + start[v], end = listed.begin() + fill[v];
    std::sort(begin, end);
    for (auto it = begin; it != end;) {
      auto next = it + 1;
      while (next != end && *next == *it) ++next;
      if (next - it == 1) {
        vertices.push_back(static_cast<Index>(v));
        vertices.push_back(*it);
      }
      it = next;
    }
  }
  std::sort(vertices.begin(), vertices.end());
  vertices.erase(std::unique(vertices.begin(), vertices.end()), vertices.end());
  return vertices;
}

namespace {

// Union–find with path halving over the pairs that for_each_pair(unite) passes to unite(a, b); every
// root is its set's smallest index, so components come out numbered by their smallest member.
template <class ForEachPair>
ComponentLabels label_components(Index count, ForEachPair&& for_each_pair) {
  std::vector<Index> parent(static_cast<std::size_t>(count));
  for (std::size_t i = 0; i < parent.size(); ++i) parent[i] = static_cast<Index>(i);
  const auto root = [&parent](Index i) {
    while (parent[static_cast<std::size_t>(i)] != i) {
      parent[static_cast<std::size_t>(i)] = parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(i)])];
      i = parent[static_cast<std::size_t>(i)];
    }
    return i;
  };
  for_each_pair([&](Index a, Index b) {
    a = root(a), b = root(b);
    if (a != b) parent[static_cast<std::size_t>(std::max(a, b))] = std::min(a, b);
  });
  ComponentLabels components;
  components.label.resize(parent.size());
  for (std::size_t i = 0; i < parent.size(); ++i) {
    const Index r = root(static_cast<Index>(i));
    if (r == static_cast<Index>(i)) {  // the smallest member of its component comes first
      components.label[i] = components.count();
      components.first.push_back(r);
    } else {
      components.label[i] = components.label[static_cast<std::size_t>(r)];
    }
  }
  return components;
}

}  // namespace

ComponentLabels component_labels(const SparseMatrix& A) {
  return label_components(static_cast<Index>(A.rows()), [&](auto&& unite) {
    for (Eigen::Index j = 0; j < A.outerSize(); ++j)
      for (SparseMatrix::InnerIterator it(A, j); it; ++it)
        if (it.value() != 0) unite(static_cast<Index>(it.row()), static_cast<Index>(it.col()));
  });
}

Index connected_components(const SparseMatrix& A) { return component_labels(A).count(); }

ComponentLabels vertex_components(const ice::Faces& F, Index vertex_count) {
  return label_components(vertex_count, [&](auto&& unite) {
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
      unite(F(f, 0), F(f, 1));
      unite(F(f, 1), F(f, 2));
    }
  });
}

std::vector<char> components_holding(const ComponentLabels& components, const std::vector<Index>& vertices) {
  std::vector<char> held(static_cast<std::size_t>(components.count()), 0);
  for (Index v : vertices)
    if (v >= 0 && static_cast<std::size_t>(v) < components.label.size())
      held[static_cast<std::size_t>(components.label[static_cast<std::size_t>(v)])] = 1;
  return held;
}

void remove_component_means(const ComponentLabels& components, const Eigen::VectorXd& weights, Eigen::VectorXd& x) {
  if (components.count() <= 1) {
    const double total = weights.sum();
    if (total != 0) x.array() -= weights.dot(x) / total;
    return;
  }
  std::vector<double> weighted(static_cast<std::size_t>(components.count()), 0.0), total(weighted.size(), 0.0);
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    const auto c = static_cast<std::size_t>(components.label[static_cast<std::size_t>(i)]);
    weighted[c] += weights[i] * x[i];
    total[c] += weights[i];
  }
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    const auto c = static_cast<std::size_t>(components.label[static_cast<std::size_t>(i)]);
    if (total[c] != 0) x[i] -= weighted[c] / total[c];
  }
}

void make_compatible(const ComponentLabels& components, const Eigen::VectorXd& weights, Eigen::VectorXd& b) {
  if (components.count() <= 1) {
    b -= weights * (b.sum() / weights.sum());
    return;
  }
  std::vector<double> sum(static_cast<std::size_t>(components.count()), 0.0), total(sum.size(), 0.0);
  for (Eigen::Index i = 0; i < b.size(); ++i) {
    const auto c = static_cast<std::size_t>(components.label[static_cast<std::size_t>(i)]);
    sum[c] += b[i];
    total[c] += weights[i];
  }
  for (Eigen::Index i = 0; i < b.size(); ++i) {
    const auto c = static_cast<std::size_t>(components.label[static_cast<std::size_t>(i)]);
    if (total[c] != 0) b[i] -= weights[i] * (sum[c] / total[c]);
  }
}

void require_connected(const SparseMatrix& A, const char* what) {
  const Index components = connected_components(A);
  if (components > 1)
    throw std::invalid_argument(std::string(what) + ": the mesh has " + std::to_string(components) +
                                " connected components; this solver pins one vertex and needs a connected mesh "
                                "(solve each component apart)");
}

}  // namespace fem
