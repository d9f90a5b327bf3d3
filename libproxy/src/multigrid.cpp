#include "ice/proxy/multigrid.h"

#include <algorithm>
#include <filesystem>
#include <stdexcept>
#include <chrono>
#include <cmath>
#include <optional>
#include <string>
#include <utility>

#include "entry_checks.h"
#include "ice/coarsen.h"
#include "ice/huge_pages.h"
#include "ice/mesh_io.h"

namespace ice::proxy {

namespace {

using detail::require;

constexpr const char* kHierarchyKind = "hierarchy";

// A hierarchy's entry: the writer points into `h` and `seconds`, which must outlive it.
EntryWriter hierarchy_entry(const MultigridHierarchy& h, const double (&seconds)[2]) {
  EntryWriter w;
  w.put_int("levels", h.num_levels());
  for (std::size_t k = 0; k < h.prolongations.size(); ++k) {
    if (!h.prolongations[k].isCompressed())
      throw std::invalid_argument("saving a hierarchy: P" + std::to_string(k) + " is not compressed");
    w.put_sparse("P" + std::to_string(k), h.prolongations[k]);
  }
  w.put("fine_order", h.fine_order.data(), h.fine_order.size());
  w.put_text("stop_reason", h.stop_reason);
  w.put("seconds", seconds, 2);
  return w;
}

void save(const Store& store, const StoreKey& key, MultigridHierarchy& h) {
  const auto start = std::chrono::steady_clock::now();
  for (Eigen::SparseMatrix<double>& P : h.prolongations) P.makeCompressed();
  const double seconds[] = {h.build_seconds, h.coarsen_seconds};
  detail::save_entry(store, kHierarchyKind, key, hierarchy_entry(h, seconds), h.cache, start);
}

// Throws std::runtime_error "where: defect" unless `h` is a hierarchy of interpolations on a mesh of
// h.fine_vertices vertices: each P_k of n_k rows and 1..n_k columns, every fine value a convex
// combination of coarse ones (non-negative weights, rows summing to 1), every coarse vertex
// interpolating somewhere (else its Galerkin level would be singular), the order a permutation.
void check_hierarchy(const MultigridHierarchy& h, const std::string& where) {
  const Index n = h.fine_vertices;
  Index rows = n;
  // One buffer for every level's row sums, offered huge pages: faulting in a fresh 4 KiB-paged
  // buffer per level took longer than the sums.
  Eigen::VectorXd row_sum_buffer(n);
  advise_huge_pages(row_sum_buffer.data(), sizeof(double) * static_cast<std::size_t>(n));
  for (std::size_t k = 0; k < h.prolongations.size(); ++k) {
    const Eigen::SparseMatrix<double>& P = h.prolongations[k];
    const std::string name = "P" + std::to_string(k);
    if (!(P.rows() == rows && P.cols() > 0 && P.cols() <= rows))
      detail::fail(where, name + " of the wrong shape (" + std::to_string(P.rows()) + " x " + std::to_string(P.cols()) +
                              ", level " + std::to_string(k) + " has " + std::to_string(rows) + " vertices)");
    auto row_sums = row_sum_buffer.head(P.rows());
    row_sums.setZero();
    for (Eigen::Index c = 0; c < P.outerSize(); ++c) {
      double largest = 0;
      for (Eigen::SparseMatrix<double>::InnerIterator it(P, c); it; ++it) {
        if (!(it.value() >= 0) || !std::isfinite(it.value())) detail::fail(where, name + " has a negative or non-finite weight");
        row_sums(it.row()) += it.value();
        largest = std::max(largest, it.value());
      }
      if (!(largest > 0)) detail::fail(where, "column " + std::to_string(c) + " of " + name + " is empty");
    }
    for (Eigen::Index i = 0; i < row_sums.size(); ++i)
      if (!(std::abs(row_sums(i) - 1.0) <= 1e-10))
        detail::fail(where, "row " + std::to_string(i) + " of " + name + " does not sum to 1");
    rows = static_cast<Index>(P.cols());
  }
  if (!h.fine_order.empty()) {
    require(static_cast<Index>(h.fine_order.size()) == n, where, "the fine order has the wrong size");
    std::vector<char> seen(static_cast<std::size_t>(n), 0);
    for (Index v : h.fine_order) {
      require(v >= 0 && v < n && !seen[static_cast<std::size_t>(v)], where, "the fine order is not a permutation");
      seen[static_cast<std::size_t>(v)] = 1;
    }
  }
}

// The hierarchy an entry holds, checked (std::runtime_error naming `path` otherwise).
MultigridHierarchy hierarchy_from_entry(const EntryReader& entry, const std::string& path, Index n) {
  MultigridHierarchy h;
  h.fine_vertices = n;
  const std::int64_t levels = entry.integer("levels");
  require(levels >= 1 && levels <= 1000, path, "a level count out of range");
  h.prolongations.reserve(static_cast<std::size_t>(levels - 1));
  for (std::int64_t k = 0; k + 1 < levels; ++k)  // swapped in: Eigen 3.4's sparse matrices have no move constructor
    entry.sparse("P" + std::to_string(k)).swap(h.prolongations.emplace_back());
  h.fine_order = entry.ints("fine_order");
  check_hierarchy(h, path);
  h.stop_reason = entry.text("stop_reason");
  const std::vector<double> seconds = entry.doubles("seconds");
  require(seconds.size() == 2, path, "build times of the wrong size");
  h.build_seconds = seconds[0];
  h.coarsen_seconds = seconds[1];
  return h;
}

// The stored hierarchy, checked (detail::load_entry: a miss or damage leaves std::nullopt and says so in `cache`).
std::optional<MultigridHierarchy> load(const Store& store, const StoreKey& key, Index n, CacheReport& cache) {
  return detail::load_entry<MultigridHierarchy>(store, kHierarchyKind, key, cache, [&](const EntryReader& entry, const std::string& path) {
    return hierarchy_from_entry(entry, path, n);
  });
}

}  // namespace

Index MultigridHierarchy::level_vertices(int k) const {
  if (k < 0 || k >= num_levels()) throw std::out_of_range("MultigridHierarchy::level_vertices: no such level");
  if (k == 0) return fine_vertices;
  return static_cast<Index>(prolongations[static_cast<std::size_t>(k - 1)].cols());
}

double MultigridHierarchy::grid_complexity() const {
  const Index n0 = level_vertices(0);
  if (n0 == 0) return 1;
  double sum = 0;
  for (int k = 0; k < num_levels(); ++k) sum += static_cast<double>(level_vertices(k));
  return sum / static_cast<double>(n0);
}

fem::PoissonMultigrid MultigridHierarchy::poisson_multigrid(const fem::MultigridOptions& options) const {
  return fem::PoissonMultigrid{prolongations, options, false, fine_order};
}

StoreKey multigrid_hierarchy_key(const TriangleMesh& mesh, const HierarchyOptions& o) {
  KeyHasher h(kHierarchyKind);
  h.add_matrix(mesh.V).add_matrix(mesh.F);
  h.add(o.ratio).add(static_cast<std::int64_t>(o.coarsest_vertices)).add(o.max_levels).add(o.area_weight);
  h.add(static_cast<int>(o.coarsening)).add(static_cast<int>(o.set_order)).add(o.strong_neighbour_share);
  h.add(o.remove_boundary).add(o.reorder);
  std::vector<Index> locked = o.locked_vertices;  // a set: order and repeats do not change the result
  std::sort(locked.begin(), locked.end());
  locked.erase(std::unique(locked.begin(), locked.end()), locked.end());
  h.add_bytes(locked.data(), locked.size() * sizeof(Index));
  // Independent-set levels are the same for every thread count; greedy levels run ice::coarsen,
  // whose result depends on its default region count.
  h.add(o.coarsening == LevelCoarsening::greedy ? coarsening_regions(CoarsenOptions{}) : 0);
  // Through the tufted cover: keyed only where the mesh needs it (an oriented manifold's hierarchy is
  // the same with either choice, and keeps the key it had before the choice existed).
  if (solved_on_tufted_cover(mesh, o.nonmanifold)) h.add(static_cast<int>(o.nonmanifold));
  return h.finish();
}

void save_multigrid_hierarchy_file(const std::filesystem::path& path, const TriangleMesh& mesh,
                                   const MultigridHierarchy& hierarchy, bool overwrite) {
  if (hierarchy.fine_vertices != mesh.V.rows())
    throw std::invalid_argument("save_multigrid_hierarchy_file: the hierarchy's finest level has " +
                                std::to_string(hierarchy.fine_vertices) + " vertices, the mesh " +
                                std::to_string(mesh.V.rows()));
  try {
    check_hierarchy(hierarchy, "save_multigrid_hierarchy_file");
  } catch (const std::runtime_error& e) {
    throw std::invalid_argument(e.what());
  }
  require_writable(path.string(), overwrite);
  const bool compressed = std::all_of(hierarchy.prolongations.begin(), hierarchy.prolongations.end(),
                                      [](const Eigen::SparseMatrix<double>& P) { return P.isCompressed(); });
  MultigridHierarchy copy;  // made only when some level is not compressed
  if (!compressed) {
    copy = hierarchy;
    for (Eigen::SparseMatrix<double>& P : copy.prolongations) P.makeCompressed();
  }
  const double seconds[] = {hierarchy.build_seconds, hierarchy.coarsen_seconds};
  write_entry_file(path, kHierarchyKind, detail::file_key(kHierarchyKind, mesh),
                   hierarchy_entry(compressed ? hierarchy : copy, seconds));
}

MultigridHierarchy load_multigrid_hierarchy_file(const std::filesystem::path& path, const TriangleMesh& mesh) {
  const auto start = std::chrono::steady_clock::now();
  const EntryReader entry = detail::read_file_for(path, kHierarchyKind, mesh);
  MultigridHierarchy h = hierarchy_from_entry(entry, path.string(), static_cast<Index>(mesh.V.rows()));
  h.cache.load_seconds = seconds_since(start);
  return h;
}

MultigridHierarchy multigrid_hierarchy(const TriangleMesh& mesh, const HierarchyOptions& options, const Store& store) {
  std::optional<StoreKey> key;
  CacheReport cache;
  if (store.enabled()) {
    key = multigrid_hierarchy_key(mesh, options);
    if (std::optional<MultigridHierarchy> stored = load(store, *key, static_cast<Index>(mesh.V.rows()), cache))
      return std::move(*stored);
  }
  Hierarchy built = build_hierarchy(mesh, options);
  MultigridHierarchy h;
  h.fine_vertices = static_cast<Index>(mesh.V.rows());
  h.prolongations = std::move(built.prolongations);
  h.fine_order = std::move(built.fine_order);
  h.stop_reason = std::move(built.stop_reason);
  h.build_seconds = built.seconds;
  h.coarsen_seconds = built.coarsen_seconds;
  h.cache = std::move(cache);
  if (key) save(store, *key, h);
  return h;
}

}  // namespace ice::proxy
