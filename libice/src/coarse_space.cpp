#include "ice/coarse_space.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>
#include <stdexcept>
#include <string>
#include <utility>

#include "ice/prolongation.h"
#include "ice/qem.h"
#include "locality_numbering.h"
#include "ice/wall_time.h"
#include "cover_copies.h"

namespace ice {

CoarseSpace::CoarseSpace(CoarseSpace&& other) noexcept { *this = std::move(other); }

CoarseSpace& CoarseSpace::operator=(CoarseSpace&& other) noexcept {
  if (this == &other) return *this;
  mesh = std::move(other.mesh);
  inserted = std::move(other.inserted);
  P.swap(other.P);
  other.P.resize(0, 0);
  summary = std::move(other.summary);
  triangulation = std::move(other.triangulation);
  triangulation_order = std::move(other.triangulation_order);
  triangulation_face_order = std::move(other.triangulation_face_order);
  mapped_copy = std::move(other.mapped_copy);
  Eigen::SparseMatrix<double> qem_P;  // handed over as P is (a moved QemResult would copy it)
  if (other.qem_result) qem_P.swap(other.qem_result->P);
  qem_result = std::move(other.qem_result);
  if (qem_result) qem_result->P.swap(qem_P);
  return *this;
}

const char* to_string(CoarseningMethod method) { return method == CoarseningMethod::qem ? "qem" : "ice"; }

const char* to_string(QemGeometry geometry) {
  return geometry == QemGeometry::intrinsic_delaunay ? "intrinsic_delaunay" : "extrinsic";
}

const char* to_string(ProxyUse use) { return use == ProxyUse::geodesic ? "geodesic" : "poisson_heat"; }

CoarsenOptions recommended_coarsen_options(ProxyUse use) {
  CoarsenOptions options;
  if (use == ProxyUse::geodesic) {
    options.area_weight = 0.9;
    options.normalize_curvature = false;
  } else {
    options.area_weight = 0.5;
    options.normalize_curvature = true;
  }
  return options;
}

const char* to_string(FineGeometry geometry) {
  return geometry == FineGeometry::intrinsic_delaunay ? "intrinsic_delaunay" : "input";
}

Index CoarseSpaceSummary::removed() const { return ice ? ice->removed : qem ? qem->collapses : 0; }

StopReason CoarseSpaceSummary::stop_reason() const {
  if (ice) return ice->stop_reason;
  return target_reached ? StopReason::TargetReached : StopReason::NothingRemovable;
}

namespace {

using Clock = std::chrono::steady_clock;

// The sizes every summary carries, from the finished space.
void record_sizes(CoarseSpace& space, CoarseningMethod method, Index input_vertices) {
  space.summary.method = method;
  space.summary.input_vertices = input_vertices;
  space.summary.coarse_vertices = space.mesh.num_vertices();
  space.summary.coarse_faces = static_cast<Index>(space.mesh.F.rows());
}

// `twin` (a gluing of faces) with face face_order[i] moved to row i (corners keep their order).
std::vector<Index> twin_in_face_order(const std::vector<Index>& twin, const std::vector<Index>& face_order) {
  std::vector<Index> new_face(face_order.size());
  for (std::size_t i = 0; i < face_order.size(); ++i) new_face[static_cast<std::size_t>(face_order[i])] = static_cast<Index>(i);
  std::vector<Index> glued(twin.size(), kInvalid);
  for (std::size_t i = 0; i < face_order.size(); ++i)
    for (std::size_t k = 0; k < 3; ++k) {
      const Index t = twin[3 * static_cast<std::size_t>(face_order[i]) + k];
      if (t != kInvalid) glued[3 * i + k] = 3 * new_face[static_cast<std::size_t>(t / 3)] + t % 3;
    }
  return glued;
}

// The triangulation of `mesh`, its faces glued by `twin` (null: by vertex pairs), built in its
// locality numbering (detail::locality_numbering), whose order[new] = input vertex lands in *order;
// in the input's own numbering (*order empty) when `renumber` is false or the mesh cannot be
// renumbered (its defects are then reported as usual).
IntrinsicTriangulation triangulation_for_locality(const TriangleMesh& mesh, const std::vector<Index>* twin, bool renumber,
                                                  std::vector<Index>* order, std::vector<Index>* face_order = nullptr) {
  order->clear();
  if (face_order) face_order->clear();
  const auto as_given = [&] {
    return twin ? IntrinsicTriangulation::from_glued_faces(mesh.F, face_lengths_from_positions(mesh.V, mesh.F), *twin)
                : IntrinsicTriangulation::from_mesh(mesh.V, mesh.F);
  };
  if (!renumber) return as_given();
  detail::LocalityNumbering local = detail::locality_numbering(mesh);
  if (local.order.empty()) return as_given();
  IntrinsicTriangulation T = twin ? IntrinsicTriangulation::from_glued_faces(local.F, local.face_lengths(mesh.V),
                                                                               twin_in_face_order(*twin, local.face_order))
                                  : IntrinsicTriangulation::from_lengths(local.F, local.face_lengths(mesh.V));
  *order = std::move(local.order);
  if (face_order) *face_order = std::move(local.face_order);
  return T;  // the renumbered faces are freed here, before the caller's work on T
}

// The input-surface points of T's inserted vertices (in vertex order, as locate_inserted_vertices
// lists them), each pulled back through T's history as a point (a segment of length 0) from a
// corner of a face at it; `face_order`: the input face of each initial face slot (empty: itself).
std::vector<InputSurfacePoint> inserted_points_from_history(const IntrinsicTriangulation& T, const std::vector<Index>& face_order) {
  std::vector<std::vector<FaceSegment>> points;
  for (Index v = T.num_input_vertices(); v < T.num_vertex_slots(); ++v) {
    if (!T.vertex_alive(v)) continue;
    const Index h = T.vertex_halfedge(v), f = T.face(h);
    FaceSegment at;
    at.face = f;
    Index g = T.halfedge(f);
    for (int k = 0; k < 3; ++k, g = T.next(g))
      if (g == h) at.from[k] = at.to[k] = 1;
    points.push_back({at});
  }
  points = pull_back(T.history(), std::move(points));
  std::vector<InputSurfacePoint> inserted;
  inserted.reserve(points.size());
  for (const std::vector<FaceSegment>& point : points) {
    InputSurfacePoint p;
    p.face = face_order.empty() ? point.front().face : face_order[static_cast<std::size_t>(point.front().face)];
    p.bary = point.front().from;
    inserted.push_back(p);
  }
  return inserted;
}

// The coarse mesh and P of T (whose input vertex t is the mesh's vertex order[t]) in the mesh's
// numbering: P's rows by input vertex, the coarse vertices in increasing order of their input
// vertices (as compact() lists them when T is in the mesh's own numbering); faces stay as listed.
void coarse_mesh_and_prolongation(const IntrinsicTriangulation& T, const std::vector<Index>& order, CoarseSpace& space) {
  CompactMesh& C = space.mesh;
  C = T.compact();
  if (order.empty()) {
    space.P = prolongation(T, C);
    return;
  }
  const Index coarse = C.num_vertices();
  std::vector<Index> by_input(static_cast<std::size_t>(coarse));
  std::iota(by_input.begin(), by_input.end(), 0);
  // Inserted vertices (to_input kInvalid) keep their place after the input ones.
  const Index input_count = static_cast<Index>(order.size());
  const auto input_of = [&](Index c) {
    const Index t = C.to_input[static_cast<std::size_t>(c)];
    return t == kInvalid ? input_count + c : order[static_cast<std::size_t>(t)];
  };
  std::sort(by_input.begin(), by_input.end(), [&](Index a, Index b) { return input_of(a) < input_of(b); });
  std::vector<Index> renumbered(static_cast<std::size_t>(coarse)), to_input(static_cast<std::size_t>(coarse));
  for (Index i = 0; i < coarse; ++i) {
    renumbered[static_cast<std::size_t>(by_input[static_cast<std::size_t>(i)])] = i;
    const Index input = input_of(by_input[static_cast<std::size_t>(i)]);
    to_input[static_cast<std::size_t>(i)] = input < input_count ? input : kInvalid;
  }
  for (Eigen::Index f = 0; f < C.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) C.F(f, k) = renumbered[static_cast<std::size_t>(C.F(f, k))];
  C.to_input = std::move(to_input);
  C.vertex_count = coarse;
  // P with the final coarse columns, T's input vertex t in row order[t].
  for (Index& c : C.from_input)
    if (c != kInvalid) c = renumbered[static_cast<std::size_t>(c)];
  space.P = prolongation(T, C, order);
  std::vector<Index> from_input(C.from_input.size());
  for (std::size_t t = 0; t < order.size(); ++t) from_input[static_cast<std::size_t>(order[t])] = C.from_input[t];
  C.from_input = std::move(from_input);
}

// The fine intrinsic Delaunay mesh of T (not yet coarsened; its input vertex t is the mesh's vertex
// order[t], empty: t itself), faces named by input vertex.
FineMesh fine_delaunay_mesh(IntrinsicTriangulation T, const std::vector<Index>& order) {
  FineMesh fine;
  fine.geometry = FineGeometry::intrinsic_delaunay;
  fine.flips = T.flip_to_delaunay();
  CompactMesh compact = T.compact();  // no vertex removed: compact indices are T's input indices
  fine.F = std::move(compact.F);
  fine.L = std::move(compact.L);
  fine.twin = std::move(compact.twin);  // sides keep their faces: renaming vertices leaves it valid
  fine.vertex_count = compact.vertex_count;
  if (!order.empty())
    for (Eigen::Index f = 0; f < fine.F.rows(); ++f)
      for (int k = 0; k < 3; ++k) fine.F(f, k) = order[static_cast<std::size_t>(fine.F(f, k))];
  return fine;
}

CoarseSpace ice_coarse_space(const TriangleMesh& mesh, const std::vector<Index>* twin, const CoarseSpaceOptions& options,
                             FineMesh* fine) {
  // The coarsener works in a numbering with memory locality; the result is given back in the
  // mesh's own.
  std::vector<Index> order;
  const auto triangulation_start = Clock::now();
  const bool record_history = options.keep_method_state && options.record_history;
  std::vector<Index> face_order;
  IntrinsicTriangulation T =
      triangulation_for_locality(mesh, twin, options.locality_numbering, &order, record_history ? &face_order : nullptr);
  double fine_mesh_seconds = 0;
  if (fine) {  // fine_mesh() would build this triangulation again: a copy is cheaper
    const auto fine_start = Clock::now();
    *fine = fine_delaunay_mesh(T, order);
    fine_mesh_seconds = seconds_since(fine_start);
  }
  if (record_history) T.record_history(true);
  const double triangulation_seconds = seconds_since(triangulation_start) - fine_mesh_seconds;
  CoarsenOptions coarsen_options = options.coarsen;
  std::vector<Index> new_index(order.size());  // mesh vertex -> T's input vertex (empty: the same)
  for (std::size_t i = 0; i < order.size(); ++i) new_index[static_cast<std::size_t>(order[i])] = static_cast<Index>(i);
  if (!order.empty())
    for (Index& v : coarsen_options.locked_vertices)  // coarsen() ignores indices out of range: so does this
      if (v >= 0 && v < static_cast<Index>(new_index.size())) v = new_index[static_cast<std::size_t>(v)];
  CoarseSpace space;
  const CoarsenResult result = coarsen(T, coarsen_options);
  if (options.refinement) {
    const auto refine_start = Clock::now();
    space.summary.refinement = refine_delaunay(T, *options.refinement);
    // The input faces in T's numbering (rows as in the mesh) locate the inserted vertices.
    Faces faces_in_t = mesh.F;
    if (!order.empty())
      for (Eigen::Index f = 0; f < faces_in_t.rows(); ++f)
        for (int k = 0; k < 3; ++k) faces_in_t(f, k) = new_index[static_cast<std::size_t>(faces_in_t(f, k))];
    // With the history, exactly: each inserted vertex pulled back onto the input faces (else
    // located by walking the map, which is not affine on input faces: ~1e-2 off in coordinates).
    space.inserted = record_history ? inserted_points_from_history(T, face_order) : locate_inserted_vertices(T, faces_in_t);
    space.summary.refinement_seconds = seconds_since(refine_start);
  }
  const auto prolongation_start = Clock::now();
  coarse_mesh_and_prolongation(T, order, space);
  space.summary.prolongation_seconds = seconds_since(prolongation_start);
  space.summary.triangulation_seconds = triangulation_seconds;
  space.summary.fine_mesh_seconds = fine_mesh_seconds;
  space.summary.target_reached = result.stop_reason == StopReason::TargetReached;
  space.summary.ice = result;
  if (options.keep_method_state) {
    space.triangulation = std::move(T);
    space.triangulation_order = std::move(order);
    space.triangulation_face_order = std::move(face_order);
  }
  record_sizes(space, CoarseningMethod::ice, static_cast<Index>(mesh.V.rows()));
  return space;
}

}  // namespace

CoarseSpace coarse_space_from_qem(QemResult qem, QemGeometry geometry, bool keep_method_state) {
  const auto start = Clock::now();
  CoarseSpace space;
  QemOutcome outcome;
  if (geometry == QemGeometry::intrinsic_delaunay) {
    int flips = 0;
    try {
      space.mesh = qem_intrinsic_delaunay_mesh(qem, &flips);
    } catch (const std::invalid_argument& e) {
      throw std::runtime_error(std::string("the QEM mesh cannot be triangulated intrinsically: ") + e.what());
    }
    outcome.intrinsic_delaunay_flips = flips;
  } else {
    space.mesh = qem_extrinsic_mesh(qem);
  }
  space.P = std::move(qem.P);
  outcome.collapses = qem.collapses;
  outcome.guard_relaxed = qem.guard_relaxed;
  outcome.max_distance = qem.max_distance;
  outcome.mean_distance = qem.mean_distance;
  outcome.decimate_seconds = qem.decimate_seconds;
  outcome.map_seconds = qem.map_seconds;
  outcome.geometry = geometry;
  space.summary.target_reached = qem.target_reached;
  space.summary.qem = outcome;
  record_sizes(space, CoarseningMethod::qem, qem.input_vertices);
  if (keep_method_state) space.qem_result = std::move(qem);
  space.summary.seconds = seconds_since(start);
  return space;
}

CoarseSpace build_coarse_space(const TriangleMesh& mesh, const CoarseSpaceOptions& options, FineMesh* fine_delaunay) {
  if (solved_on_tufted_cover(mesh, options.nonmanifold))
    return build_coarse_space(tufted_cover(mesh), options, fine_delaunay);
  const auto start = Clock::now();
  CoarseSpace space;
  // ICE in the locality numbering starts from the very triangulation fine_mesh() flips: it hands a
  // copy over. Otherwise the fine mesh is made apart.
  const bool shared = options.method == CoarseningMethod::ice && options.locality_numbering;
  if (options.method == CoarseningMethod::qem) {
    if (options.refinement)
      throw std::invalid_argument("build_coarse_space: refinement works on ICE's intrinsic coarse mesh, not on QEM's");
    if (std::isfinite(options.coarsen.max_error))
      throw std::invalid_argument("build_coarse_space: max_error bounds the ICE error metric; QEM takes a vertex target");
    QemOptions q;
    q.target_vertices = options.coarsen.target_vertices;
    q.target_ratio = options.coarsen.target_ratio;
    q.locked_vertices = options.coarsen.locked_vertices;
    q.remove_boundary = options.coarsen.remove_boundary;
    space = coarse_space_from_qem(qem_coarsen(mesh, q), options.qem_geometry, options.keep_method_state);
  } else {
    space = ice_coarse_space(mesh, nullptr, options, shared ? fine_delaunay : nullptr);
  }
  if (fine_delaunay && !shared) {
    const auto fine_start = Clock::now();
    *fine_delaunay = fine_mesh(mesh, FineGeometry::intrinsic_delaunay);
    space.summary.fine_mesh_seconds = seconds_since(fine_start);
  }
  space.summary.seconds = seconds_since(start) - space.summary.fine_mesh_seconds;
  return space;
}

std::vector<CoarsePoint> fine_to_coarse_map(const CoarseSpace& space) {
  std::vector<CoarsePoint> map;
  if (space.qem_result) {
    if (space.summary.qem && space.summary.qem->geometry != QemGeometry::extrinsic)
      throw std::invalid_argument(
          "fine_to_coarse_map: the closest-point map of QEM lies in the QEM mesh's faces, not in the faces of its "
          "intrinsic Delaunay triangulation (see CoarseSpace::qem_result->map)");
    map.reserve(space.qem_result->map.size());
    for (const QemPoint& q : space.qem_result->map) map.push_back({q.coarse_vertex, q.face, q.bary});
    return map;
  }
  if (!space.triangulation)
    throw std::invalid_argument("fine_to_coarse_map: build the coarse space with keep_method_state");
  const IntrinsicTriangulation& T = *space.triangulation;
  const bool covered = space.summary.tufted_cover;
  if (covered && space.mapped_copy.size() != space.mesh.from_input.size())
    throw std::invalid_argument("fine_to_coarse_map: a tufted cover's space without the copy each input vertex is mapped by");
  // Face slot -> compact face (compact() lists the live slots in order, corners from halfedge(f)).
  std::vector<Index> compact_face(static_cast<std::size_t>(T.num_face_slots()), kInvalid);
  Index next_face = 0;
  for (Index f = 0; f < T.num_face_slots(); ++f)
    if (T.face_alive(f)) compact_face[f] = next_face++;
  // On a cover the triangulation's input vertices are copies: each input vertex reads its mapped copy.
  const auto points = static_cast<Index>(covered ? space.mapped_copy.size() : static_cast<std::size_t>(T.num_input_vertices()));
  map.resize(static_cast<std::size_t>(points));
  const std::vector<Index>& order = space.triangulation_order;
  for (Index q = 0; q < points; ++q) {
    const Index t = covered ? space.mapped_copy[static_cast<std::size_t>(q)] : q;
    const SurfacePoint s = T.location(t);
    const Index p = covered || order.empty() ? q : order[static_cast<std::size_t>(t)];
    CoarsePoint& point = map[p];
    point.coarse_vertex = space.mesh.from_input[p];
    Index face = s.face;
    point.bary = s.bary;
    if (s.is_vertex()) {  // the face of its outgoing half-edge, weight 1 at that corner
      const Index h = T.vertex_halfedge(s.vertex);
      face = T.face(h);
      Index g = T.halfedge(face);
      point.bary = {0, 0, 0};
      for (int k = 0; k < 3; ++k, g = T.next(g))
        if (g == h) point.bary[k] = 1;
    }
    point.face = compact_face[face];
  }
  return map;
}

Positions coarse_vertex_positions(const TriangleMesh& mesh, const CoarseSpace& space) {
  const CompactMesh& coarse = space.mesh;
  Positions positions(coarse.num_vertices(), 3);
  std::size_t next_inserted = 0;
  for (Index c = 0; c < coarse.num_vertices(); ++c) {
    const Index input = coarse.to_input[static_cast<std::size_t>(c)];
    if (input != kInvalid) {
      positions.row(c) = mesh.V.row(input);
      continue;
    }
    if (next_inserted >= space.inserted.size())
      throw std::invalid_argument("coarse_vertex_positions: an inserted coarse vertex without its input-surface point");
    const InputSurfacePoint& p = space.inserted[next_inserted++];
    positions.row(c).setZero();
    for (int k = 0; k < 3; ++k) positions.row(c) += p.bary[static_cast<std::size_t>(k)] * mesh.V.row(mesh.F(p.face, k));
  }
  return positions;
}

FineMesh fine_mesh(const TriangleMesh& mesh, FineGeometry geometry, NonmanifoldInput nonmanifold) {
  if (solved_on_tufted_cover(mesh, nonmanifold)) return fine_mesh(tufted_cover(mesh), geometry);
  FineMesh fine;
  fine.geometry = geometry;
  if (geometry == FineGeometry::input) {
    fine.F = mesh.F;
    fine.L = face_lengths_from_positions(mesh.V, mesh.F);
    fine.vertex_count = static_cast<Index>(mesh.V.rows());
    return fine;
  }
  // Built and flipped in the locality numbering (as ICE coarsens), faces then named by input vertex.
  std::vector<Index> order;
  IntrinsicTriangulation T = triangulation_for_locality(mesh, nullptr, true, &order);
  return fine_delaunay_mesh(std::move(T), order);
}

namespace {

// Names the corners of a fine mesh of the cover by their input vertices.
FineMesh on_input_vertices(const TuftedCover& cover, FineMesh fine) {
  for (Eigen::Index f = 0; f < fine.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) fine.F(f, k) = cover.to_input[static_cast<std::size_t>(fine.F(f, k))];
  fine.vertex_count = cover.input_vertex_count;
  return fine;
}

/// Per input vertex of `cover`, the copy its point of the fine-to-coarse map is read from, as the
/// triangulation's vertex (`order`: triangulation vertex -> copy; empty: the same): a surviving copy
/// (`coarse_of_copy` not kInvalid) before a removed one — its point is then its coarse vertex — and
/// among those the largest `area` (the copy whose fan carries most of the vertex's surface), ties
/// to the lower copy.
std::vector<Index> mapped_copies(const TuftedCover& cover, const std::vector<Index>& order, const std::vector<Index>& coarse_of_copy,
                                 const Eigen::VectorXd& area) {
  const std::size_t copies = cover.to_input.size();
  std::vector<Index> vertex_of_copy(copies);
  for (std::size_t t = 0; t < copies; ++t) vertex_of_copy[order.empty() ? t : static_cast<std::size_t>(order[t])] = static_cast<Index>(t);
  std::vector<Index> best(static_cast<std::size_t>(cover.input_vertex_count), kInvalid);
  auto better = [&](Index a, Index b) {  // copy a before copy b
    const bool a_kept = coarse_of_copy[static_cast<std::size_t>(a)] != kInvalid;
    const bool b_kept = coarse_of_copy[static_cast<std::size_t>(b)] != kInvalid;
    if (a_kept != b_kept) return a_kept;
    return area[a] > area[b];
  };
  for (std::size_t c = 0; c < copies; ++c) {
    Index& chosen = best[static_cast<std::size_t>(cover.to_input[c])];
    if (chosen == kInvalid || better(static_cast<Index>(c), chosen)) chosen = static_cast<Index>(c);
  }
  for (Index& c : best) c = vertex_of_copy[static_cast<std::size_t>(c)];
  return best;
}

/// The options that coarsen the copies of `cover` (distinct_sheets' result) for `options`, asked of its
/// input vertices: ICE only, no refinement (std::invalid_argument naming `caller` otherwise).
/// Locked input vertices: every copy of each (they become one coarse vertex when merged). With
/// `lock_junctions`, so are the vertices where separate sheets meet at the vertex alone: once the
/// copies are merged, a removed copy there would part the coarse mesh where the input is joined
/// (coarse marching could not cross; P alone would join them). Copies left apart join nothing there.
/// A vertex target counts input vertices; the cover has more (copies): the same ratio of its own.
CoarseSpaceOptions options_on_copies(const TuftedCover& cover, const CoarseSpaceOptions& options, bool lock_junctions,
                                     const char* caller) {
  if (options.method != CoarseningMethod::ice)
    throw std::invalid_argument(std::string(caller) + ": a tufted cover is coarsened by ICE only (QEM decimates an extrinsic "
                                "surface; the cover's front and back sheets coincide in space)");
  if (options.refinement) throw std::invalid_argument(std::string(caller) + ": no refinement on a tufted cover");
  CoarseSpaceOptions cover_options = options;
  std::vector<Index> locked = lock_junctions ? detail::sheet_junctions(cover) : std::vector<Index>();
  locked.insert(locked.end(), options.coarsen.locked_vertices.begin(), options.coarsen.locked_vertices.end());
  if (!locked.empty()) cover_options.coarsen.locked_vertices = detail::copies_of(cover.to_input, cover.input_vertex_count, locked);
  if (options.coarsen.target_vertices > 0 && cover.input_vertex_count > 0)
    cover_options.coarsen.target_vertices = static_cast<Index>(std::llround(
        static_cast<double>(options.coarsen.target_vertices) * static_cast<double>(cover.to_input.size()) /
        static_cast<double>(cover.input_vertex_count)));
  return cover_options;
}

}  // namespace

CoarseSpace build_coarse_space(const TuftedCover& full_cover, const CoarseSpaceOptions& options, FineMesh* fine_delaunay) {
  const auto start = Clock::now();
  // Coarsened once per distinct sheet (a mirror sheet would double every basis function); the
  // fine mesh stays the whole cover's (the robust Laplacian).
  const TuftedCover cover = distinct_sheets(full_cover);
  const bool whole = cover.mesh.F.rows() == full_cover.mesh.F.rows();
  const CoarseSpaceOptions cover_options = options_on_copies(cover, options, /*lock_junctions=*/true, "build_coarse_space");
  FineMesh cover_fine;
  const bool shared = fine_delaunay && options.locality_numbering && whole;
  CoarseSpace space = ice_coarse_space(cover.mesh, &cover.twin, cover_options, shared ? &cover_fine : nullptr);
  const auto map_start = Clock::now();
  // Coarse copies of one input vertex become one coarse vertex, as the fine mesh's copies are one
  // fine vertex: where two sheets lie on each other (the inside and outside of a closed surface
  // joined elsewhere), ICE keeps the same vertices on both, and their basis functions, mapped to
  // the input, would coincide (a singular Galerkin mass). The coarse mesh keeps the cover's gluing.
  CompactMesh& C = space.mesh;
  std::vector<Index> input_of_copy(static_cast<std::size_t>(C.vertex_count));
  for (Index c = 0; c < C.vertex_count; ++c)
    input_of_copy[static_cast<std::size_t>(c)] = cover.to_input[static_cast<std::size_t>(C.to_input[static_cast<std::size_t>(c)])];
  detail::MergedCopies merged = detail::merge_copies(input_of_copy, cover.input_vertex_count);
  for (Eigen::Index f = 0; f < C.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) C.F(f, k) = merged.unknown[static_cast<std::size_t>(C.F(f, k))];
  const Eigen::VectorXd copy_area = cover_vertex_areas(cover);
  if (space.triangulation) space.mapped_copy = mapped_copies(cover, space.triangulation_order, C.from_input, copy_area);
  space.P = cover_to_input(cover, copy_area) * space.P * merged.spread();
  space.P.makeCompressed();
  C.vertex_count = static_cast<Index>(merged.to_input.size());
  C.to_input = std::move(merged.to_input);
  C.from_input = std::move(merged.from_input);
  space.summary.coarse_vertices = C.vertex_count;
  space.summary.input_vertices = cover.input_vertex_count;
  space.summary.tufted_cover = true;
  space.summary.prolongation_seconds += seconds_since(map_start);
  if (fine_delaunay) {
    const auto fine_start = Clock::now();
    *fine_delaunay = shared ? on_input_vertices(full_cover, std::move(cover_fine)) : fine_mesh(full_cover, FineGeometry::intrinsic_delaunay);
    space.summary.fine_mesh_seconds += seconds_since(fine_start);
  }
  space.summary.seconds = seconds_since(start) - space.summary.fine_mesh_seconds;
  return space;
}

FineMesh fine_mesh(const TuftedCover& cover, FineGeometry geometry) { return on_input_vertices(cover, fine_mesh_on_copies(cover, geometry)); }

FineMesh fine_mesh_on_copies(const TuftedCover& cover, FineGeometry geometry) {
  FineMesh fine;
  fine.geometry = geometry;
  if (geometry == FineGeometry::input) {
    static_cast<IntrinsicMesh&>(fine) = cover.intrinsic_mesh();
    return fine;
  }
  std::vector<Index> order;
  IntrinsicTriangulation T = triangulation_for_locality(cover.mesh, &cover.twin, true, &order);
  return fine_delaunay_mesh(std::move(T), order);
}

CoarseSpace build_coarse_space_on_copies(const TuftedCover& cover, const CoarseSpaceOptions& options) {
  const auto start = Clock::now();
  CoarseSpace space = ice_coarse_space(cover.mesh, &cover.twin, options_on_copies(cover, options, /*lock_junctions=*/false, "build_coarse_space_on_copies"),
                                       nullptr);
  space.summary.seconds = seconds_since(start);
  return space;
}

}  // namespace ice
