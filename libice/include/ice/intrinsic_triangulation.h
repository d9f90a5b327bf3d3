#pragma once
/// \file intrinsic_triangulation.h
/// An intrinsic triangulation: a Δ-complex (connectivity) plus one positive length per edge, with
/// every vertex of the input mesh tracked as a point on it.
///
/// Connectivity
///  - Half-edges come in twin pairs: `twin(h) == h ^ 1`. An edge is a pair; edge e owns half-edges
///    2e and 2e+1. On the boundary the twin of an interior half-edge is an *exterior* half-edge
///    (`face(h) == kInvalid`). Adjacency comes only from this pairing and from `next`, never from
///    vertex pairs, so self-edges (tail == head), multi-edges and faces glued to themselves are all
///    representable.
///  - Interior half-edges of a face form a 3-cycle under `next`, counter-clockwise. Exterior
///    half-edges have no `next`.
///  - `vertex_halfedge(v)` is an outgoing interior half-edge; at a boundary vertex it is the first one
///    counter-clockwise, i.e. the one whose twin is exterior.
///  - Elements are never renumbered by local operations: a flip keeps every half-edge, edge and face
///    index (the flipped edge is re-used), removals mark elements dead. `compact()` exports a clean
///    mesh with index maps.
///  - Vertex indices are the input mesh's vertex indices; removed vertices become tracked points.
///
/// Angular coordinates (tangent frames): each outgoing half-edge at v carries an angle in [0, 2π),
/// corner angles accumulated counter-clockwise and scaled by 2π/Θ_v (interior) or 2π/(Θ_v + π)
/// (boundary, where the first outgoing half-edge has coordinate 0 and the exterior gets the
/// remaining share). Flips assign the new half-edges their coordinates without moving the others;
/// operations that change Θ_v re-accumulate v's coordinates from its reference half-edge.
///
/// Tracked points: every input vertex p is either still a vertex or lies in a live face f with
/// barycentric coordinates (b0, b1, b2) w.r.t. the corners (tail of halfedge(f), of next, of
/// next·next). Flips, flattening and removals update them so that, on a flat mesh, every point keeps
/// its planar position exactly (up to round-off).
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "ice/mesh.h"
#include "ice/large_array.h"
#include "ice/triangle_geometry.h"
#include "ice/triangulation_history.h"
#include "ice/vertex_star.h"

namespace ice {

/// Where an input vertex is now: a vertex of the triangulation, or a point in a face.
struct SurfacePoint {
  Index vertex = kInvalid;              ///< the vertex, when the input vertex survives
  Index face = kInvalid;                ///< otherwise the face containing it
  std::array<double, 3> bary{0, 0, 0};  ///< barycentric coordinates w.r.t. the face's corners
  bool is_vertex() const { return vertex != kInvalid; }
};

/// Why a vertex removal did or did not happen.
enum class RemovalStatus {
  Removed,
  NotAVertex,            ///< already removed
  FlattenFailed,         ///< Newton found no valid scale
  FaceOnlyAtVertex,      ///< a face of its star has all three corners at the vertex
  NoConvexFlip,          ///< could not flip down to degree 3 (or 2 on the boundary)
  BoundaryLoopTooSmall,  ///< removing it would shrink a boundary loop below two edges
  TopologyChange,        ///< removal would change the topology (e.g. the last face of a component)
};
const char* to_string(RemovalStatus status);

class IntrinsicTriangulation {
 public:
  /// Builds the triangulation of an extrinsic mesh. Preconditions (checked, std::invalid_argument
  /// on violation): every vertex is referenced, indices are in range, the surface is an oriented
  /// edge-manifold (each undirected edge has at most two faces, traversed in opposite directions),
  /// every face is non-degenerate. Several components and boundary loops are fine.
  static IntrinsicTriangulation from_mesh(const Positions& V, const Faces& F);

  /// Builds from faces and per-face lengths (ice/mesh.h convention); the two faces of an edge must
  /// agree on its length to 1e-12 relative. Same preconditions as from_mesh.
  static IntrinsicTriangulation from_lengths(const Faces& F, const FaceLengths& L);
  /// The same, freeing L once read (before the half-edge arrays are built: a lower peak).
  static IntrinsicTriangulation from_lengths(const Faces& F, FaceLengths&& L);

  /// Builds any Δ-complex from faces, per-face lengths and the gluing of their sides (CompactMesh::twin
  /// convention): self-edges and several edges between two vertices are fine. Preconditions (checked,
  /// std::invalid_argument): the gluing is an involution without fixed points that joins sides with
  /// the same end vertices in opposite directions, glued sides agree on their length to 1e-12
  /// relative, every vertex 0..max is used and its corners form one fan, faces are non-degenerate.
  /// compact() and this are inverse: from_glued_faces(c.F, c.L, c.twin).compact() == c.
  static IntrinsicTriangulation from_glued_faces(const Faces& F, const FaceLengths& L, const std::vector<Index>& twin);

  // ---- sizes ------------------------------------------------------------------------------
  /// Vertices of the input (tracked points): vertex slots 0 .. num_input_vertices() − 1.
  Index num_input_vertices() const { return static_cast<Index>(points_.size()); }
  /// Vertex slots: the input's, then one per vertex inserted by insert_vertex / split_edge.
  Index num_vertex_slots() const { return static_cast<Index>(vertices_.size()); }
  /// True for a vertex that insert_vertex or split_edge made (it is no input vertex).
  bool is_inserted_vertex(Index v) const { return v >= num_input_vertices(); }
  Index num_vertices() const { return num_vertices_; }
  Index num_edges() const { return num_edges_; }
  Index num_faces() const { return num_faces_; }
  Index num_halfedge_slots() const { return static_cast<Index>(2 * edges_.size()); }
  Index num_face_slots() const { return static_cast<Index>(faces_.size()); }
  int euler_characteristic() const { return num_vertices_ - num_edges_ + num_faces_; }

  // ---- connectivity -----------------------------------------------------------------------
  static Index twin(Index h) { return h ^ 1; }
  static Index edge(Index h) { return h >> 1; }
  Index next(Index h) const { return hnext(h); }
  Index prev(Index h) const { return hprev(h); }  ///< interior half-edges only
  Index tail(Index h) const { return htail(h); }
  Index head(Index h) const { return htail(h ^ 1); }
  Index face(Index h) const { return hface(h); }
  Index halfedge(Index f) const { return fhalfedge(f); }
  Index vertex_halfedge(Index v) const { return vhalfedge(v); }
  bool halfedge_alive(Index h) const { return htail(h) != kInvalid; }
  bool face_alive(Index f) const { return fhalfedge(f) != kInvalid; }
  bool vertex_alive(Index v) const { return vhalfedge(v) != kInvalid; }
  bool is_exterior(Index h) const { return hface(h) == kInvalid; }
  bool is_boundary_edge(Index h) const { return is_exterior(h) || is_exterior(h ^ 1); }
  bool is_boundary_vertex(Index v) const { return vertices_[v].boundary != 0; }
  /// Next outgoing interior half-edge counter-clockwise around tail(h), or kInvalid past the last
  /// one at a boundary vertex.
  Index rotate_ccw(Index h) const {
    const Index t = prev(h) ^ 1;
    return is_exterior(t) ? kInvalid : t;
  }
  /// Number of corners at v (faces counted with multiplicity).
  int degree(Index v) const;
  /// Calls f(h) for every outgoing interior half-edge of v, counter-clockwise from vertex_halfedge.
  template <class F>
  void for_each_outgoing(Index v, F&& f) const {
    const Index start = vhalfedge(v);
    Index h = start;
    do {
      f(h);
      h = rotate_ccw(h);
    } while (h != kInvalid && h != start);
  }

  // ---- geometry ---------------------------------------------------------------------------
  double length(Index h) const { return elength(h >> 1); }
  /// Corner angle at tail(h) in face(h) (between h and prev(h)).
  double corner_angle(Index h) const {
    return angle_opposite(length(h), length(prev(h)), length(next(h)));
  }
  /// Cotangent of the angle opposite h in face(h) (0 for an exterior half-edge).
  double cotan_opposite(Index h) const {
    return is_exterior(h) ? 0.0 : cot_opposite(length(next(h)), length(prev(h)), length(h));
  }
  /// Cotan weight ½(cot α + cot β) of the edge of h (one term on the boundary).
  double cotan_weight(Index h) const { return 0.5 * (cotan_opposite(h) + cotan_opposite(h ^ 1)); }
  double face_area(Index f) const;
  double total_area() const;
  /// Angle sum Θ_v (stored; kept current by every operation).
  double angle_sum(Index v) const { return vsum(v); }
  /// Θ_v recomputed from the lengths.
  double compute_angle_sum(Index v) const;
  /// Gaussian curvature 2π − Θ at interior vertices, geodesic curvature π − Θ at boundary ones.
  double curvature(Index v) const;
  /// Σ curvature over live vertices; equals 2πχ (Gauss–Bonnet).
  double total_curvature() const;
  /// Angular coordinate of the outgoing half-edge h at tail(h), in [0, 2π). Meaningful only while
  /// frames_maintained().
  double angular_coordinate(Index h) const { return hangle(h); }
  /// Whether operations keep the angular coordinates up to date (true unless maintain_frames(false)).
  bool frames_maintained() const { return frames_maintained_; }
  /// Stops (false) or resumes (true) maintaining the angular coordinates. Angle sums, lengths and
  /// tracked points are maintained either way, so curvature, flattening, removals, flips, P and the
  /// coarse mesh agree with a framed run up to round-off (not bit for bit: the angle sums are summed
  /// differently, and a tie may then break the other way). Without frames, flips and flattenings
  /// skip the coordinates' updates (a flattening of a star with distinct neighbours adjusts each
  /// neighbour's angle sum by its two changed corners; other stars re-accumulate the neighbours'
  /// sums), validate() skips the coordinates' check, compacted() copies carry the setting, and the
  /// ICE error metric (whose transports read them) refuses the triangulation; ice::coarsen resumes
  /// them itself. Resuming recomputes every live vertex's frame from the lengths (on the hardware's
  /// threads, at most 8, for 100,000+ vertex slots, as the builders do). For callers that read no
  /// frame: the multigrid hierarchy's independent-set levels (docs/measurements.md, "Multigrid
  /// hierarchy: level coarsening").
  void maintain_frames(bool on);
  /// Records (true) every local operation from now on in history(), or stops and clears it (false):
  /// what pulls the current faces' curves back to the faces it had when recording started (call it
  /// right after building to reach the input's)
  /// (ice/triangulation_history.h; the exact tracing of ice/coarse_tracing.h). Off by default: about
  /// 100 bytes per operation (a coarsening makes ~10 per removal). Copies carry the history;
  /// compacted() copies start without one.
  void record_history(bool on);
  bool records_history() const { return recording_; }
  const TriangulationHistory& history() const { return history_; }
  /// While one is alive on a thread, the operations that thread makes on a recording triangulation
  /// go to its shard instead of the triangulation's history: a region coarsened on a thread of its
  /// own (ice::coarsen's parallel phase), whose shard is appended after the region's round.
  class HistoryShard {
   public:
    explicit HistoryShard(TriangulationHistory& shard);
    ~HistoryShard();
    HistoryShard(const HistoryShard&) = delete;
    HistoryShard& operator=(const HistoryShard&) = delete;

   private:
    TriangulationHistory* previous_;
  };
  /// Moves a shard's records to the end of the history (in the order the shards are appended),
  /// leaving the shard empty.
  void append_history(TriangulationHistory&& shard) {
    if (recording_) history_.append(std::move(shard));
  }
  /// The factor that maps corner angles at v to angular coordinates.
  double angle_scale(Index v) const {
    constexpr double kTurn = 6.283185307179586476925286766559;
    return is_boundary_vertex(v) ? kTurn / (vsum(v) + 0.5 * kTurn) : kTurn / vsum(v);
  }
  /// True when the edge of h is locally Delaunay: the opposite angles sum to ≤ π, i.e. the cotan
  /// weight is ≥ −tolerance. Boundary edges are always Delaunay.
  bool is_delaunay(Index h, double tolerance = kDelaunayTolerance) const {
    return is_boundary_edge(h) || cotan_weight(h) >= -tolerance;
  }
  static constexpr double kDelaunayTolerance = 1e-10;

  // ---- operations -------------------------------------------------------------------------
  /// Intrinsic flip of the (interior) edge of h. Returns false and changes nothing when the edge is
  /// on the boundary, when both sides belong to one face, or when the diamond is not strictly
  /// convex. Otherwise h now runs between the two formerly opposite corners.
  bool flip(Index h);
  /// Flips non-Delaunay edges until every edge is Delaunay. Returns the number of flips.
  int flip_to_delaunay();
  /// A part of the mesh that local operations may change: the vertices with label[v] == value.
  /// Threads that each work in their own part never write the same element (see coarsen's
  /// parallel mode).
  struct WriteRegion {
    const std::uint8_t* label = nullptr;
    std::uint8_t value = 0;
    /// If given, flip_to_delaunay_around appends the half-edges it left unchecked because a corner
    /// of their diamond lies outside (some may be Delaunay; repeats possible), so that a caller can
    /// restore Delaunay across the seams from them afterwards.
    std::vector<Index>* skipped = nullptr;
    bool contains(Index v) const { return label[v] == value; }
  };
  /// As flip_to_delaunay, but starts from the edges of the given faces (and spreads as needed).
  /// If `touched` is given, the endpoints of every flipped diamond are appended to it. With a
  /// `region`, only edges whose four diamond corners lie in it are considered (others may be left
  /// non-Delaunay).
  int flip_to_delaunay_around(const std::vector<Index>& faces, std::vector<Index>* touched = nullptr,
                              const WriteRegion* region = nullptr);
  /// Flattens v (one-vertex CETM): scales its edges so Θ_v = 2π (interior) or π (boundary), to
  /// 1e-13 relative. Newton starts from `initial_log_scale` (e.g. a scale an earlier, looser
  /// compute_flattening found; 0 = unscaled). On failure nothing changes.
  FlattenResult flatten_vertex(Index v, double initial_log_scale = 0);
  /// Computes the scale that would flatten v without changing anything, to a relative angle-sum
  /// tolerance (flatten_vertex uses 1e-13; a cost estimate can use less). See ice/vertex_star.h.
  FlattenResult compute_flattening(Index v, double tolerance = 1e-13, double initial_log_scale = 0) const;
  /// Reads the star of v (a live vertex), counter-clockwise from vertex_halfedge(v), into `star`
  /// (re-using its storage). Consecutive corners share a spoke: corner k's in_halfedge is the twin
  /// of corner k+1's halfedge (and, at an interior vertex, the last corner's of the first's), so
  /// corner k's in_vertex is corner k+1's out_vertex.
  void read_star(Index v, VertexStar& star) const;
  /// Removes v: flattens it, flips it down to degree 3 (interior) or 2 (boundary), merges its
  /// faces into one triangle, and re-locates the tracked points. A degree-4 star whose centre lies
  /// on a diagonal (opposite corners summing to π, as on regular grids) cannot be flipped to degree
  /// 3; it is replaced by the two triangles on either side of that diagonal instead. Does not restore Delaunay: every
  /// face whose geometry changed (the merged face and the faces made by the degree-reducing flips)
  /// is appended to *changed_faces, and the endpoints of flipped edges to *touched. When the removal
  /// fails after the flattening, the triangulation stays valid (v remains, flattened and possibly
  /// flipped; its star's faces are then reported as changed). `flattening_hint` is a starting
  /// scale for the flattening's Newton iteration (see flatten_vertex); it changes only round-off.
  RemovalStatus remove_vertex(Index v, std::vector<Index>* changed_faces = nullptr,
                              std::vector<Index>* touched = nullptr, double flattening_hint = 0);

  /// Inserts a vertex at the point of face f with barycentric coordinates `bary` (w.r.t. the corners
  /// tail(halfedge(f)), its next, its next·next; all > 0, summing to 1) and connects it to the three
  /// corners: f becomes three faces (f and two new ones; appended to *new_faces with f). The new
  /// vertex is flat (Θ = 2π); the corners' angle sums do not change; the tracked points of f are
  /// re-located in the three faces exactly. Returns the new vertex's slot (num_vertex_slots() − 1),
  /// or kInvalid (nothing changed) when a new face would be thinner than flip() allows (smallest-angle
  /// sine 1e-7). Does not restore Delaunay. Throws std::invalid_argument for a dead face or coordinates outside
  /// the open face.
  Index insert_vertex(Index f, const std::array<double, 3>& bary, std::vector<Index>* new_faces = nullptr);
  /// Inserts a vertex on the edge of h at fraction t ∈ (0, 1) of its length from tail(h) and connects
  /// it to the opposite corner of each face along the edge (two faces become four; a boundary edge's
  /// face becomes two, and the new vertex lies on the boundary with Θ = π). Points re-located exactly.
  /// Returns the new vertex, or kInvalid (nothing changed) when both sides of the edge belong to one
  /// face or a new face would be thinner than flip() allows. The faces that changed or were made are appended to *new_faces.
  Index split_edge(Index h, double t, std::vector<Index>* new_faces = nullptr);

  // ---- tracked points ---------------------------------------------------------------------
  /// Current location of input vertex p.
  SurfacePoint location(Index p) const;
  /// Input vertices tracked inside face f (for iteration; order unspecified).
  template <class F>
  void for_each_point_in_face(Index f, F&& fn) const {
    for (Index p = ffirst(f); p != kInvalid; p = points_[p].next) fn(p);
  }

  // ---- export and checks ------------------------------------------------------------------
  /// The live faces as arrays (faces + per-face lengths) with vertex maps back to the input.
  CompactMesh compact() const;
  /// A new triangulation of the live elements only, renumbered compactly (vertex i is compact
  /// vertex i of compact(), and `to_input` of *maps gives its input vertex). Connectivity is copied
  /// through the twin/next relations, so any Δ-complex (self-edges, multi-edges) carries over, and
  /// angular coordinates are kept (with frames_maintained() as here). Tracking restarts: every vertex is its own input vertex. This is
  /// how one coarsened level becomes the input of the next.
  IntrinsicTriangulation compacted(CompactMesh* maps = nullptr) const;
  /// Checks every invariant; returns an empty string when all hold, else the first few problems.
  /// `tolerance` bounds the numerical checks; stored angle sums are compared with recomputed ones to
  /// max(tolerance, 3.6e-8), the round-off that the thinnest triangles a flip may create leave behind.
  std::string validate(double tolerance = 1e-9) const;
  /// Bytes held by the arrays of this object (capacity, not size), its recorded history included.
  std::size_t memory_bytes() const;

 private:
  friend class TwoRingPrefetch;  // the coarsener's memory prefetching (libice/src/two_ring_prefetch.h)
  IntrinsicTriangulation() = default;
  // from_mesh / from_lengths after their checks: lengths per corner (3f + k), sides glued by vertex pairs.
  static IntrinsicTriangulation from_corner_lengths(const Faces& F, const std::vector<double>& lengths);
  /// `twin`: the gluing of the corners' sides (CompactMesh::twin); edges are numbered in the order the
  /// corners are listed in `order` (a permutation of the corners).
  void build(const Faces& F, const std::vector<double>& halfedge_length_by_corner, const std::vector<Index>& twin,
             const std::vector<Index>& order);
  // build()'s stages: the half-edge records of the numbered sides (returns each vertex's corner
  // count), then each vertex's outgoing half-edge and boundary flag, checking that every vertex
  // has one fan (the corners it was given).
  std::vector<Index> link_halfedges(const Faces& F, const std::vector<double>& corner_length,
                                    const std::vector<Index>& twin, const std::vector<Index>& corner_halfedge,
                                    int threads);
  void link_vertices(const std::vector<Index>& corners_at_vertex);
  // Live vertex and face slots numbered in slot order (vertices: input ones, then inserted ones),
  // kInvalid for dead slots: the numbering of compact() and compacted().
  struct CompactNumbers {
    std::vector<Index> vertex, face;
    Index vertices = 0, faces = 0;
  };
  CompactNumbers compact_numbers(int threads) const;
  CompactMesh compact(const CompactNumbers& numbers, int threads) const;
  void recompute_vertex_frame(Index v);
  FlattenResult flatten_vertex(Index v, double initial_log_scale, bool update_own_frame);
  // The new angle of the corner at tail(halfedge), between halfedge and prev(halfedge).
  struct CornerChange {
    Index halfedge;
    double corner;
  };
  // Recomputes Θ_v and v's angular coordinates (from its reference half-edge). changes == nullptr:
  // every corner from the lengths. Otherwise the listed corners take the listed values and every
  // other corner is read back from the stored coordinates; with `changed_near`, the list may hold
  // other vertices' corners too and only corners of faces touching changed_near are looked up;
  // without (kInvalid), the list holds v's changed corners only (a few: each corner is compared
  // with all of them).
  void refresh_vertex_frame(Index v, Index changed_near, const CornerChange* changes, int change_count);
  void add_point_to_face(Index p, Index f, const std::array<double, 3>& bary);
  // Storage for insertions: a new vertex slot, edge (two half-edges 2e, 2e + 1) and face slot.
  Index new_vertex(bool boundary, double angle_sum);
  Index new_edge(double length);
  Index new_face();
  void kill_face(Index f);
  void kill_edge(Index e);
  RemovalStatus remove_interior_vertex(Index v, std::vector<Index>* changed_faces, std::vector<Index>* touched,
                                       double flattening_hint);
  RemovalStatus remove_boundary_vertex(Index v, std::vector<Index>* changed_faces, std::vector<Index>* touched,
                                       double flattening_hint);
  void merge_star_into_face(Index v, const std::vector<Index>& star, std::vector<Index>* changed_faces);
  bool merge_star_along_diagonal(Index v, std::vector<Index>* changed_faces);

  // Storage: records rather than one array per attribute, so that a local operation touches few
  // cache lines. An edge record holds both of its half-edges (2e and 2e+1) and its length.
  // prev is stored although it is next∘next: walking around a vertex (prev(h)^1) then costs one
  // dependent memory access per step instead of two, which is what bounds local operations on
  // meshes larger than the caches.
  struct EdgeRecord {
    Index next[2];
    Index prev[2];
    Index tail[2];
    Index face[2];
    double angle[2];
    double length;
  };
  struct VertexRecord {
    Index halfedge;
    Index boundary;  // 1 on the boundary; boundary status never changes (kept in the padding)
    double angle_sum;
  };
  struct FaceRecord {
    Index halfedge;
    Index first_point;
  };
  // Large arrays (huge pages: the removal order jumps across them, see ice/large_array.h).
  LargeArray<EdgeRecord> edges_;
  LargeArray<VertexRecord> vertices_;
  LargeArray<FaceRecord> faces_;
  // Reference accessors used by the implementation.
  Index& hnext(Index h) { return edges_[h >> 1].next[h & 1]; }
  Index& hprev(Index h) { return edges_[h >> 1].prev[h & 1]; }
  // Makes a, b, c (interior half-edges) the 3-cycle of one face: next and prev.
  void link_face(Index a, Index b, Index c) {
    hnext(a) = b, hnext(b) = c, hnext(c) = a;
    hprev(b) = a, hprev(c) = b, hprev(a) = c;
  }
  Index& htail(Index h) { return edges_[h >> 1].tail[h & 1]; }
  Index& hface(Index h) { return edges_[h >> 1].face[h & 1]; }
  double& hangle(Index h) { return edges_[h >> 1].angle[h & 1]; }
  double& elength(Index e) { return edges_[e].length; }
  Index& fhalfedge(Index f) { return faces_[f].halfedge; }
  Index& ffirst(Index f) { return faces_[f].first_point; }
  Index& vhalfedge(Index v) { return vertices_[v].halfedge; }
  double& vsum(Index v) { return vertices_[v].angle_sum; }
  Index hnext(Index h) const { return edges_[h >> 1].next[h & 1]; }
  Index hprev(Index h) const { return edges_[h >> 1].prev[h & 1]; }
  Index htail(Index h) const { return edges_[h >> 1].tail[h & 1]; }
  Index hface(Index h) const { return edges_[h >> 1].face[h & 1]; }
  double hangle(Index h) const { return edges_[h >> 1].angle[h & 1]; }
  double elength(Index e) const { return edges_[e].length; }
  Index fhalfedge(Index f) const { return faces_[f].halfedge; }
  Index ffirst(Index f) const { return faces_[f].first_point; }
  Index vhalfedge(Index v) const { return vertices_[v].halfedge; }
  double vsum(Index v) const { return vertices_[v].angle_sum; }
  // Tracked points: one record per input vertex (32 bytes: relocating a point touches one cache
  // line), in intrusive singly linked per-face lists (points only ever leave a face all together).
  struct TrackedPoint {
    Index face;  // kInvalid while the input vertex is a vertex
    Index next;  // next point in the same face
    std::array<double, 3> bary;
  };
  LargeArray<TrackedPoint> points_;
  // Scratch space of local operations: one per thread (thread_local), so that operations allocate
  // nothing per flip or removal and threads working in disjoint regions share no scratch.
  struct PlacedPoint {
    Index point;
    Vec2 position;
  };
  static std::vector<PlacedPoint>& scratch_points();
  static std::vector<Index>& scratch_faces();
  template <class Layout>
  void collect_points(Index f, const Layout& layout, std::vector<PlacedPoint>& out);
  // Element counts change through these (atomic: threads in disjoint regions remove concurrently).
  static void decrement(Index& count) { __atomic_fetch_sub(&count, 1, __ATOMIC_RELAXED); }
  Index num_vertices_ = 0, num_edges_ = 0, num_faces_ = 0;
  bool frames_maintained_ = true;
  // The operations' record (record_history): where they go on this thread, or null when not recording.
  TriangulationHistory* history_sink();
  bool recording_ = false;
  TriangulationHistory history_;
};

/// The gluing of a mesh whose edges are named by their vertex pairs (no self- or multi-edges), in the
/// CompactMesh::twin convention. Throws std::invalid_argument for a face that repeats a vertex, an edge
/// with more than two faces, or two faces that run along an edge in the same direction.
std::vector<Index> glue_by_vertex_pairs(const Faces& F);

}  // namespace ice
