#include "ice/proxy/setup.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

#include "fem/curvature_correction.h"
#include "ice/prolongation.h"
#include "ice/wall_time.h"

namespace ice::proxy {

void require_galerkin_on_cover(bool tufted_cover, fem::CoarseOperatorKind kind) {
  if (tufted_cover && kind != fem::CoarseOperatorKind::galerkin)
    throw std::invalid_argument("a mesh solved on its tufted cover takes Galerkin coarse operators (galerkin: the cover's "
                                "own coarse Laplacian is not the input's robust Laplacian)");
}

fem::CoarseProxy make_proxy(const FineMesh& fine, const CoarseSpace& coarse, fem::CoarseOperatorKind kind,
                            fem::ProlongationKind prolongation) {
  require_galerkin_on_cover(coarse.summary.tufted_cover, kind);
  // The faces and lengths only: the proxy keeps no gluing, so none is copied.
  return fem::CoarseProxy(IntrinsicMesh{fine.F, fine.L, {}, fine.vertex_count}, coarse.mesh, coarse.P,
                          {kind, fem::MassKind::lumped, prolongation});
}

ProxySetup build_proxy_setup(const TriangleMesh& mesh, const ProxySetupOptions& options, std::optional<CoarseSpace> coarse) {
  using Clock = std::chrono::steady_clock;
  const fem::ProlongationKind resolved =
      resolve_prolongation(options.prolongation, options.operators, options.dirichlet, options.prolongation_use);
  const bool needs_fine = options.assemble || options.need_fine_mesh;
  ProxySetup setup;
  setup.fine_geometry = options.fine;
  // A mesh coarsened through its tufted cover: the cover's own coarse operators would be its
  // components' (not the input's robust Laplacian), so Galerkin only. Stored under a key that says
  // so (detail::add_mesh_and_coarsening), its fine mesh the cover's when made again.
  const bool covered = (coarse && coarse->summary.tufted_cover) || solved_on_tufted_cover(mesh, options.coarsening.nonmanifold);
  const NonmanifoldInput nonmanifold = covered ? NonmanifoldInput::tufted_cover : NonmanifoldInput::refuse;
  require_galerkin_on_cover(covered, options.operators);  // before the work
  bool fine_made = false;  // setup.fine
  std::optional<StoreKey> key;
  if (coarse) {
    setup.coarse = std::move(*coarse);
  } else {
    CoarseSpaceOptions coarsening = options.coarsening;
    coarsening.nonmanifold = nonmanifold;  // decided once
    std::vector<Index>& kept = coarsening.coarsen.locked_vertices;
    kept.insert(kept.end(), options.locked.begin(), options.locked.end());
    if (options.assemble && options.store.enabled() && !coarsening.keep_method_state && !coarsening.record_history) {
      key = proxy_setup_key(mesh, coarsening, options.fine, options.operators, resolved);
      fem::CoarseProxy::FineMeshSource source = options.restored_fine_mesh;
      if (!source && options.fine_operators) source = fine_mesh_source(mesh, options.fine, nonmanifold);
      if (std::optional<ProxySetup> stored = load_proxy_setup(options.store, *key, mesh, setup.cache, std::move(source))) {
        stored->fine_geometry = options.fine;
        if (options.need_fine_mesh) {
          const auto start = Clock::now();
          stored->fine = fine_mesh(mesh, options.fine, nonmanifold);
          stored->times.fine_mesh = seconds_since(start);
        }
        return std::move(*stored);
      }
    }
    // The fine intrinsic Delaunay mesh comes from the triangulation the coarsening starts with.
    FineMesh* shared = needs_fine && options.fine == FineGeometry::intrinsic_delaunay ? &setup.fine : nullptr;
    const auto start = Clock::now();
    setup.coarse = options.builder ? options.builder(mesh, coarsening, shared) : build_coarse_space(mesh, coarsening, shared);
    setup.times.coarsen = seconds_since(start) - setup.coarse.summary.fine_mesh_seconds;
    setup.times.fine_mesh = setup.coarse.summary.fine_mesh_seconds;
    fine_made = shared != nullptr;
  }
  if (needs_fine && !fine_made) {
    const auto start = Clock::now();
    setup.fine = fine_mesh(mesh, options.fine, nonmanifold);
    setup.times.fine_mesh += seconds_since(start);
  }
  if (options.assemble) {
    const auto start = Clock::now();
    // `new` initialised from the returned proxy itself: make_unique would move it, and a CoarseProxy's
    // move copies its sparse matrices (Eigen 3.4 has no sparse move).
    setup.proxy.reset(new fem::CoarseProxy(make_proxy(setup.fine, setup.coarse, options.operators, resolved)));
    setup.times.assemble = seconds_since(start);
  }
  // A coarsening cancelled by its progress callback is not the space its key names: never stored.
  if (key && setup.coarse.summary.stop_reason() != StopReason::Cancelled) save_proxy_setup(options.store, *key, setup);
  return setup;
}

FaceLengths curvature_corrected_lengths(const TriangleMesh& mesh, const CoarseSpace& space, const FaceLengths& lengths,
                                        double divisor) {
  return fem::curvature_corrected_lengths(intrinsic_mesh(mesh), with_lengths(space.mesh, lengths), space.P, divisor);
}

SurfaceEdgeLengths marching_lengths(const TriangleMesh& mesh, const CoarseSpace& space, bool traced,
                                    CurvatureCorrection correction, const std::vector<CoarsePoint>* map, double divisor) {
  SurfaceEdgeLengths result;
  if (traced && map)  // (not `map ? *map : fine_to_coarse_map(space)`: that copies the given map)
    result = surface_edge_lengths(mesh, space.mesh, *map, space.inserted);
  else if (traced)
    result = surface_edge_lengths(mesh, space.mesh, fine_to_coarse_map(space), space.inserted);
  else
    result.lengths = space.mesh.L;
  if (corrects_curvature(correction, space.summary.method, space.summary.tufted_cover))
    result.lengths = curvature_corrected_lengths(mesh, space, result.lengths, divisor);
  return result;
}

namespace {
// The tangent mesh of `mesh` (lengths and gluing set), its operators on `delaunay()`'s fine mesh
// with intrinsic_delaunay, else on `mesh` itself.
template <class Delaunay>
TangentMesh tangent_mesh_of(IntrinsicMesh mesh, FineGeometry geometry, bool with_operators, double time_factor, Delaunay&& delaunay) {
  TangentMesh out;
  out.mesh = std::move(mesh);
  out.frames = fem::tangent_frames(out.mesh);
  if (!with_operators) return out;
  if (geometry == FineGeometry::input) {
    out.operators = fem::vector_heat_operators(out.mesh, out.frames, time_factor);
  } else {
    FineMesh fine = delaunay();
    out.flips = fine.flips;
    out.operators = fem::vector_heat_operators(out.mesh, out.frames, fine, time_factor);
  }
  return out;
}
}  // namespace

TangentMesh tangent_mesh(const TriangleMesh& mesh, FineGeometry geometry, bool with_operators, double time_factor) {
  IntrinsicMesh input;
  input.F = mesh.F;
  input.L = face_lengths_from_positions(mesh.V, mesh.F);
  input.twin = glue_by_vertex_pairs(mesh.F);
  input.vertex_count = static_cast<Index>(mesh.V.rows());
  return tangent_mesh_of(std::move(input), geometry, with_operators, time_factor, [&] { return fine_mesh(mesh, geometry); });
}

TangentMesh tangent_mesh(const TuftedCover& cover, FineGeometry geometry, bool with_operators, double time_factor) {
  return tangent_mesh_of(cover.intrinsic_mesh(), geometry, with_operators, time_factor,
                         [&] { return fine_mesh_on_copies(cover, geometry); });
}

namespace {
// `direction` projected into v's tangent plane, of the direction's length; 0 when nothing is left.
fem::Complex projected_direction(const TangentMesh& fine, const Positions& V, Index v, const Eigen::Vector3d& direction) {
  const fem::Complex z = fem::ambient_to_tangent(fine.mesh, fine.frames, V, v, direction);
  return std::abs(z) > 1e-12 * direction.norm() ? direction.norm() * z / std::abs(z) : fem::Complex(0);
}
}  // namespace

fem::Complex tangent_direction(const TangentMesh& fine, const Positions& V, Index v, const Eigen::Vector3d& direction,
                               const std::string& name) {
  const fem::Complex z = projected_direction(fine, V, v, direction);
  if (z == fem::Complex(0))
    throw std::invalid_argument("the direction of " + name + " is normal to the surface (nothing left after projection)");
  return z;
}

CopySources sources_on_copies(const TuftedCover& cover, const TangentMesh& fine, const std::vector<Index>& sources,
                              const Eigen::MatrixXd& directions, const std::vector<long long>& labels) {
  if (directions.rows() != static_cast<Eigen::Index>(sources.size()) || directions.cols() != 3)
    throw std::invalid_argument("sources_on_copies: " + std::to_string(directions.rows()) + "x" + std::to_string(directions.cols()) +
                                " directions for " + std::to_string(sources.size()) + " sources (one 3D direction each)");
  // The copies of each input vertex: the columns of its row of the copies' averaging.
  const Eigen::SparseMatrix<double, Eigen::RowMajor> copies_of =
      copies_to_vertices(cover.to_input, cover.input_vertex_count, Eigen::VectorXd::Ones(static_cast<Eigen::Index>(cover.to_input.size())));
  if (!labels.empty() && labels.size() != sources.size())
    throw std::invalid_argument("sources_on_copies: " + std::to_string(labels.size()) + " labels for " + std::to_string(sources.size()) + " sources");
  // The sources' copies whose fan holds a face and its mirror image (the same input vertices): on an
  // open sheet's boundary the cover folds from one side to the other there, and a vector at such a
  // copy would reach the sheet's other side mirrored (averaged on the input, only its component
  // along the boundary would be left).
  std::vector<char> is_source_copy(cover.to_input.size(), 0);
  for (Index v : sources)
    if (v >= 0 && v < cover.input_vertex_count)
      for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(copies_of, v); it; ++it) is_source_copy[static_cast<std::size_t>(it.col())] = 1;
  std::vector<std::pair<Index, std::array<Index, 3>>> corners;  // (source copy, its face's input vertices, sorted)
  for (Eigen::Index f = 0; f < cover.mesh.F.rows(); ++f)
    for (int k = 0; k < 3; ++k)
      if (is_source_copy[static_cast<std::size_t>(cover.mesh.F(f, k))]) {
        std::array<Index, 3> key;
        for (int j = 0; j < 3; ++j) key[static_cast<std::size_t>(j)] = cover.to_input[static_cast<std::size_t>(cover.mesh.F(f, j))];
        std::sort(key.begin(), key.end());
        corners.emplace_back(cover.mesh.F(f, k), key);
      }
  std::sort(corners.begin(), corners.end());
  std::vector<char> folded(cover.to_input.size(), 0);
  for (std::size_t i = 1; i < corners.size(); ++i)
    if (corners[i] == corners[i - 1]) folded[static_cast<std::size_t>(corners[i].first)] = 1;
  CopySources result;
  for (std::size_t s = 0; s < sources.size(); ++s) {
    const std::string name = "source " + std::to_string(labels.empty() ? static_cast<long long>(sources[s]) : labels[s]);
    const Eigen::Vector3d d = directions.row(static_cast<Eigen::Index>(s)).transpose();
    if (sources[s] < 0 || sources[s] >= cover.input_vertex_count)
      throw std::invalid_argument("sources_on_copies: " + name + " is not a vertex of the input");
    // A copy whose sheet is normal to the direction takes none (the direction lies in another sheet's plane).
    bool any = false;
    for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(copies_of, sources[s]); it; ++it) {
      const auto c = static_cast<Index>(it.col());
      if (folded[static_cast<std::size_t>(c)])
        throw std::invalid_argument(name + " has a copy where a face and its mirror image meet (the cover folds from a "
                                           "sheet's one side to the other there, as at an open sheet's boundary in a cover "
                                           "made with boundary tufts): a vector there has no side to keep; use a cover made "
                                           "without them (ice::tufted_cover(mesh, false))");
      const fem::Complex z = projected_direction(fine, cover.mesh.V, c, d);
      if (z == fem::Complex(0)) continue;
      result.copies.push_back(c);
      result.vectors.push_back(z);
      any = true;
    }
    if (!any)
      throw std::invalid_argument("the direction of " + name + " is normal to the surface on every sheet there (nothing left "
                                  "after projection)");
  }
  return result;
}

Eigen::MatrixXd ambient_on_input(const TuftedCover& cover, const TangentMesh& fine, const Eigen::VectorXcd& field) {
  // Copies the field did not reach (sides of the sheets not joined to a source's) weigh nothing: a
  // vertex's vector is the mean over the copies that carry one.
  // (A vertex no copy of which carries one: the plain mean of zeros.)
  Eigen::VectorXd weight = cover_vertex_areas(cover);
  for (Eigen::Index c = 0; c < weight.size(); ++c)
    if (field(c) == fem::Complex(0)) weight(c) = 0;
  return copies_to_vertices(cover.to_input, cover.input_vertex_count, weight) *
         fem::tangent_to_ambient(fine.mesh, fine.frames, cover.mesh.V, field);
}

fem::VectorHeatProxy make_vector_proxy(const TangentMesh& fine, const CoarseSpace& coarse, const std::vector<CoarsePoint>& map,
                                       fem::VectorOperatorKind kind, double time_factor) {
  const fem::TangentFrames coarse_frames = fem::tangent_frames(coarse.mesh);
  if (fine.operators)
    return fem::VectorHeatProxy(fine.mesh, fine.frames, *fine.operators, coarse.mesh, coarse_frames, map, coarse.P, kind,
                                time_factor);
  if (kind == fem::VectorOperatorKind::galerkin)
    throw std::logic_error("make_vector_proxy: Galerkin operators need the fine operators (tangent_mesh with_operators)");
  return fem::VectorHeatProxy(fine.mesh, fine.frames, coarse.mesh, coarse_frames, map, coarse.P, kind, time_factor);
}

bool vector_sweep_traces(const CoarseSpace& coarse) {
  return traces_lengths(CoarseLengths::automatic, coarse.summary.method, true);
}

fem::VectorSweepProxy make_vector_sweep(const TriangleMesh& mesh, const TangentMesh& fine, const CoarseSpace& coarse,
                                        const std::vector<CoarsePoint>& map, const fem::DistanceSweepOptions& options,
                                        const SurfaceEdgeLengths* given) {
  if (!fine.operators) throw std::logic_error("make_vector_sweep: the sweep needs the fine operators (tangent_mesh with_operators)");
  if (!given && map.size() != static_cast<std::size_t>(mesh.V.rows()))  // e.g. a cover's copies: nothing to trace on `mesh`
    throw std::invalid_argument("make_vector_sweep: a map of " + std::to_string(map.size()) + " points for a mesh of " +
                                std::to_string(mesh.V.rows()) + " vertices (give the lengths of a cover's copies)");
  const SurfaceEdgeLengths lengths =
      given ? *given : marching_lengths(mesh, coarse, vector_sweep_traces(coarse), CurvatureCorrection::automatic, &map);
  return fem::VectorSweepProxy(*fine.operators, fem::ProxyGeodesicSolver(with_lengths(coarse.mesh, lengths.lengths), coarse.P), options);
}

}  // namespace ice::proxy
