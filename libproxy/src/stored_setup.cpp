#include "ice/proxy/setup.h"

#include <algorithm>
#include <filesystem>
#include <chrono>
#include <cmath>
#include <memory>
#include <numeric>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>

#include "entry_checks.h"
#include "stored_space.h"
#include "ice/huge_pages.h"
#include "ice/mesh_io.h"

namespace ice::proxy {

namespace {

using detail::require;

constexpr const char* kProxyKind = "proxy";

// A copy of `m` in buffers offered huge pages before the copy touches them (copying a fine-size P
// into fresh 4 KiB pages costs more in page faults than in the copy).
Eigen::SparseMatrix<double> copy_of(const Eigen::SparseMatrix<double>& m) {
  Eigen::SparseMatrix<double> copy(m.rows(), m.cols());
  copy.resizeNonZeros(m.nonZeros());
  const auto nnz = static_cast<std::size_t>(m.nonZeros());
  advise_huge_pages(copy.innerIndexPtr(), sizeof(int) * nnz);
  advise_huge_pages(copy.valuePtr(), sizeof(double) * nnz);
  std::copy(m.outerIndexPtr(), m.outerIndexPtr() + m.outerSize() + 1, copy.outerIndexPtr());
  std::copy(m.innerIndexPtr(), m.innerIndexPtr() + nnz, copy.innerIndexPtr());
  std::copy(m.valuePtr(), m.valuePtr() + nnz, copy.valuePtr());
  return copy;
}


}  // namespace

StoreKey proxy_setup_key(const TriangleMesh& mesh, const CoarseSpaceOptions& coarsening, FineGeometry geometry,
                         fem::CoarseOperatorKind kind, fem::ProlongationKind prolongation) {
  KeyHasher h(kProxyKind);
  detail::add_mesh_and_coarsening(h, mesh, coarsening);
  h.add(to_string(geometry)).add(static_cast<int>(kind)).add(fem::to_string(prolongation));
  h.add(static_cast<int>(fem::MassKind::lumped)).add(fem::kProlongationSmoothingWeight);
  return h.finish();
}

namespace {

// A setup's entry: the writer points into the setup and into the buffers here, which must outlive it.
struct SetupEntry {
  EntryWriter writer;
  detail::CoarseSpaceArrays coarse_arrays;
  Eigen::VectorXd mass;

  // The proxy's arrays are written by reference: arrays() would copy them.
  SetupEntry(const CoarseSpace& coarse, const fem::CoarseProxy& proxy, FineGeometry geometry) : coarse_arrays(writer, coarse) {
    EntryWriter& w = writer;
    w.put_text("fine_geometry", to_string(geometry));
    w.put_int("proxy.kind", static_cast<int>(proxy.kind()));
    w.put_int("proxy.mass_kind", static_cast<int>(proxy.mass_kind()));
    w.put_int("proxy.prolongation", static_cast<int>(proxy.prolongation_kind()));
    // P itself is the coarse space's (the proxy's barycentric one); only its smoothing is stored apart.
    if (fem::is_smoothed(proxy.prolongation_kind())) w.put_sparse("proxy.P", proxy.prolongation());
    mass = proxy.fine_mass().diagonal();
    w.put("proxy.fine_mass", mass.data(), static_cast<std::size_t>(mass.size()));
    w.put_sparse("proxy.coarse_laplacian", proxy.coarse_laplacian());
    w.put_sparse("proxy.coarse_mass", proxy.coarse_mass());
  }
  SetupEntry(const SetupEntry&) = delete;
  SetupEntry& operator=(const SetupEntry&) = delete;
};

}  // namespace

void save_proxy_setup(const Store& store, const StoreKey& key, ProxySetup& setup) {
  const auto start = std::chrono::steady_clock::now();
  const SetupEntry entry(setup.coarse, *setup.proxy, setup.fine_geometry);
  detail::save_entry(store, kProxyKind, key, entry.writer, setup.cache, start);
}

fem::CoarseProxy::FineMeshSource fine_mesh_source(const TriangleMesh& mesh, FineGeometry geometry, NonmanifoldInput nonmanifold) {
  return [input = std::make_shared<const TriangleMesh>(mesh), geometry, nonmanifold](IntrinsicMesh& fine) {
    fine = static_cast<IntrinsicMesh&&>(fine_mesh(*input, geometry, nonmanifold));
  };
}

namespace {

// The setup an entry holds, checked: throws std::runtime_error naming `path` when the entry is not
// consistent, std::invalid_argument when the restored proxy finds its arrays inconsistent.
ProxySetup setup_from_entry(const EntryReader& entry, const std::string& path, const TriangleMesh& mesh,
                            fem::CoarseProxy::FineMeshSource fine_mesh) {
    ProxySetup setup;
    const auto n = static_cast<Index>(mesh.V.rows());
    setup.coarse = detail::coarse_space_from_entry(entry, path, mesh);
    CoarseSpace& c = setup.coarse;
    if (entry.integer("proxy.kind") != 0 && entry.integer("proxy.kind") != 1) detail::fail(path, "proxy.kind is not a known value");
    const std::int64_t prolongation = entry.integer("proxy.prolongation");
    if (prolongation < 0 || prolongation > static_cast<std::int64_t>(fem::ProlongationKind::smoothed_twice))
      detail::fail(path, "proxy.prolongation is not a known value");
    require(entry.integer("proxy.mass_kind") == static_cast<int>(fem::MassKind::lumped), path, "the fine mass is not lumped");
    fem::CoarseProxyArrays a;
    a.kind = static_cast<fem::CoarseOperatorKind>(entry.integer("proxy.kind"));
    a.mass_kind = static_cast<fem::MassKind>(entry.integer("proxy.mass_kind"));
    a.prolongation_kind = static_cast<fem::ProlongationKind>(prolongation);
    if (fem::is_smoothed(a.prolongation_kind)) {
      entry.sparse("proxy.P").swap(a.P);
      const Eigen::VectorXd row_sums = a.P * Eigen::VectorXd::Ones(a.P.cols());
      for (Eigen::Index i = 0; i < row_sums.size(); ++i)
        require(std::abs(row_sums(i) - 1.0) <= 1e-10, path, "a row of the smoothed P does not sum to 1");
      copy_of(c.P).swap(a.barycentric);
    } else {
      copy_of(c.P).swap(a.P);
    }
    const std::vector<double> mass = entry.doubles("proxy.fine_mass");
    require(static_cast<Index>(mass.size()) == n, path, "fine mass of the wrong size");
    a.fine_mass = Eigen::SparseMatrix<double>(n, n);  // diagonal: written as its compressed arrays
    a.fine_mass.resizeNonZeros(n);
    advise_huge_pages(a.fine_mass.valuePtr(), sizeof(double) * static_cast<std::size_t>(n));
    std::iota(a.fine_mass.outerIndexPtr(), a.fine_mass.outerIndexPtr() + n + 1, 0);
    std::iota(a.fine_mass.innerIndexPtr(), a.fine_mass.innerIndexPtr() + n, 0);
    std::copy(mass.begin(), mass.end(), a.fine_mass.valuePtr());
    entry.sparse("proxy.coarse_laplacian").swap(a.coarse_laplacian);
    entry.sparse("proxy.coarse_mass").swap(a.coarse_mass);
    a.coarse = IntrinsicMesh{c.mesh.F, c.mesh.L, {}, c.mesh.vertex_count};
    // The fine mesh is made again only if something asks for the fine operators (polishing, the
    // Galerkin heat method): the proxy's own operators are all here.
    if (!fine_mesh)
      fine_mesh = [](IntrinsicMesh&) {
        throw std::logic_error("this coarse proxy was loaded from a store without a source of its fine mesh: its fine "
                               "operators (polishing, the Galerkin heat method) are not available");
      };
    setup.proxy = std::make_unique<fem::CoarseProxy>(std::move(a), std::move(fine_mesh));
    return setup;
}

}  // namespace

std::optional<ProxySetup> load_proxy_setup(const Store& store, const StoreKey& key, const TriangleMesh& mesh,
                                           CacheReport& cache, fem::CoarseProxy::FineMeshSource fine_mesh) {
  return detail::load_entry<ProxySetup>(store, kProxyKind, key, cache, [&](const EntryReader& entry, const std::string& path) {
    return setup_from_entry(entry, path, mesh, std::move(fine_mesh));
  });
}

void save_proxy_setup_file(const std::filesystem::path& path, const TriangleMesh& mesh, const CoarseSpace& coarse,
                           const fem::CoarseProxy& proxy, FineGeometry geometry, bool overwrite) {
  const Eigen::SparseMatrix<double>& P = proxy.barycentric_prolongation();
  // Shapes first: a sparse expression of matrices of other shapes reads out of bounds.
  const bool same_P = coarse.P.rows() == P.rows() && coarse.P.cols() == P.cols() && coarse.P.isApprox(P, 0.0);
  if (coarse.P.rows() != mesh.V.rows() || !same_P)
    throw std::invalid_argument("save_proxy_setup_file: the coarse space and the proxy are not one setup of this mesh of " +
                                std::to_string(mesh.V.rows()) + " vertices");
  require_writable(path.string(), overwrite);
  const SetupEntry entry(coarse, proxy, geometry);
  write_entry_file(path, kProxyKind, detail::file_key(kProxyKind, mesh), entry.writer);
}

void save_proxy_setup_file(const std::filesystem::path& path, const TriangleMesh& mesh, const ProxySetup& setup,
                           bool overwrite) {
  if (!setup.proxy) throw std::invalid_argument("save_proxy_setup_file: the setup has no assembled proxy");
  save_proxy_setup_file(path, mesh, setup.coarse, *setup.proxy, setup.fine_geometry, overwrite);
}

ProxySetup load_proxy_setup_file(const std::filesystem::path& path, const TriangleMesh& mesh,
                                 fem::CoarseProxy::FineMeshSource fine_mesh) {
  const auto start = std::chrono::steady_clock::now();
  const EntryReader entry = detail::read_file_for(path, kProxyKind, mesh);
  try {  // invalid_argument: an unknown geometry, or the restored proxy's own checks
    const FineGeometry geometry = parse<FineGeometry>(entry.text("fine_geometry"), "the fine geometry");
    // A setup through the tufted cover (marked in its coarse space) makes the cover's fine mesh again.
    const NonmanifoldInput nonmanifold = entry.has("coarse.tufted_cover") ? NonmanifoldInput::tufted_cover : NonmanifoldInput::refuse;
    if (!fine_mesh) fine_mesh = fine_mesh_source(mesh, geometry, nonmanifold);
    ProxySetup setup = setup_from_entry(entry, path.string(), mesh, std::move(fine_mesh));
    setup.fine_geometry = geometry;
    setup.cache.load_seconds = seconds_since(start);
    return setup;
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(path.string() + ": " + e.what());
  }
}

}  // namespace ice::proxy
