#pragma once
/// \file coarse_tracing.h
/// The coarse mesh drawn on the input surface: every coarse (intrinsic) edge traced as a polyline
/// across the input triangles, and every input face labelled by the coarse face that contains it.
///
///   ice::CoarseSpaceOptions options;
///   options.keep_method_state = options.record_history = true;   // ICE, its history kept
///   const ice::CoarseSpace space = ice::build_coarse_space(mesh, options);
///   const ice::CoarseTracing tracing = ice::trace_coarse_mesh(mesh, space);
///   for (const ice::TracedEdge& e : tracing.edges) draw(ice::traced_polyline(mesh.V, mesh.F, e));
///
/// Two ways, one result type:
///
/// **Exact, from the coarsening's history** (trace_coarse_mesh(mesh, space) of a space built with
/// CoarseSpaceOptions::record_history). Every operation of the coarsening maps straight segments to
/// straight segments piece by piece (ice/triangulation_history.h), so each coarse edge is pulled back
/// through the recorded operations, last first, onto the input faces: the preimage of the edge under
/// the fine-to-coarse map itself. Each input face is labelled by pushing its barycentre forward the
/// same way. Every edge is traced and none crosses another on the project's and the shared meshes
/// (tests: the shared meshes and the project's, Δ-complex and refined coarse meshes; the runs are in
/// docs/measurements.md, "Coarse tracing: the exact pull-back"). Cost: the history's memory grows
/// with the removals and is held while the coarse space lives, and the pull-back is serial (beside
/// the push-forward on a second thread); its memory and time against the walk are in the same section.
///
/// **A walk over the map** (trace_coarse_mesh(F, coarse, map, ...), and the space overload without
/// a history): the fine-to-coarse map places every input vertex in a coarse face, so every input
/// triangle has an image in the coarse metric, the triangle spanned by its vertices' images laid out
/// by unfolding the coarse faces between them. A coarse edge is a straight segment in the layout of
/// its face; the walk crosses the images of the input triangles, each crossing read back on the input
/// triangle through the same barycentric coordinates. Input vertices near the edge are laid out in
/// the stars of its two end vertices, unfolded about each end and cut opposite the edge; vertices
/// further away by a search over unfoldings that pass through the triangle's image (with positions,
/// the image whose shape is nearest the input triangle's). A boundary edge is the input's boundary
/// chain between its ends. Limits: ICE's map is piecewise affine on the triangulations the
/// coarsening went through, not on input triangles, so an input triangle large against the coarse
/// faces is bent by it and its straight image can fold; the walk then fails on such edges (reported,
/// never drawn): a small share overall, more on meshes whose triangles are large against the coarse
/// faces (docs/measurements.md, "Coarse tracing: the walk"). Where the metric is the input's (an
/// intrinsic Delaunay retriangulation of it, or ICE on a flat mesh) the walk's polylines have the
/// intrinsic lengths to round-off, with rare exceptions on CAD slivers (same section).
///
/// Properties (tests/test_coarse_tracing.cpp): a traced edge runs from its tail to its head through
/// segments inside single input faces that join end to end, its positions along the edge increase
/// from 0 to its intrinsic length, two traced edges meet only at coarse vertices (checked here too:
/// edges that cross are marked `crossed`). On a coarsened curved mesh the polyline's length on the
/// input surface differs from the intrinsic length by the metric distortion of ICE's flattening
/// (CoarseTracing::length_ratio_*); an exact trace may bend inside an input face (the map is not
/// affine there), the walk's never does.
///
/// Δ-complex coarse meshes (self-edges, several edges between two vertices) are traced like any
/// other edge; an edge with an end at a vertex inserted by refinement (not an input vertex) is traced
/// from (or to) that vertex's point inside an input face.
#include <array>
#include <vector>

#include "ice/coarse_space.h"
#include "ice/mesh.h"
#include "ice/refinement.h"

namespace ice {

/// One straight piece of a traced edge, inside one input face.
struct TracedSegment {
  Index face = kInvalid;                  ///< input face (row of the input F)
  std::array<double, 3> from{0, 0, 0};    ///< barycentric coordinates of the start w.r.t. the face's corners
  std::array<double, 3> to{0, 0, 0};      ///< and of the end
  double from_param = 0, to_param = 0;    ///< positions along the coarse edge, 0 at its tail, its length at its head
};

enum class TraceStatus {
  traced,        ///< reached the head vertex
  left_surface,  ///< the walk reached the input's boundary before the head (an inconsistent map)
  lost,          ///< an input vertex could not be placed, or the walk went backwards (an inconsistent map)
  step_limit,    ///< more steps than input faces
  crossed,       ///< reached its head but crosses another traced edge (a vertex laid out in the wrong copy)
};
const char* to_string(TraceStatus status);

struct TracedEdge {
  Index side = kInvalid;                  ///< the coarse side traced: 3f + k, running from corner k to k + 1 of face f
  Index tail = kInvalid, head = kInvalid; ///< coarse vertices
  double length = 0;                      ///< the intrinsic (coarse) length
  TraceStatus status = TraceStatus::traced;
  std::vector<TracedSegment> segments;    ///< tail to head; what was traced before a failure otherwise
  /// A traced edge's shortest_traced_length, set by trace_coarse_mesh when given positions; −1
  /// otherwise.
  double surface_length = -1;
};

struct CoarseTracing {
  /// One per coarse edge: interior edges from the side with the smaller index, boundary edges from their face.
  /// Untraced edges keep the segments walked before the failure (not drawn: not on the edge).
  std::vector<TracedEdge> edges;
  /// Input face -> the coarse face containing the image of its barycentre (laid out from its corner
  /// deepest inside a coarse face). With every edge traced, faces between the same traced edges get
  /// the same label (tested).
  std::vector<Index> face_patch;
  /// Input vertex -> the coarse face of its map point (a coarse vertex: the face the map names).
  std::vector<Index> vertex_patch;
  Index traced = 0, failed = 0;           ///< edges by outcome
  /// Over traced edges: length of the polyline on the input surface / intrinsic length (1 where the
  /// coarse metric is the input's), set by trace_coarse_mesh when positions are given.
  double length_ratio_min = 1, length_ratio_max = 1;
};

/// Traces every edge of `coarse` across the input faces `F`. `map` is the fine-to-coarse map
/// (one CoarsePoint per input vertex, faces in coarse's numbering: ice::fine_to_coarse_map);
/// `inserted` the input-surface points of vertices inserted by refinement, in coarse vertex order
/// after the input ones (CoarseSpace::inserted). Preconditions (std::invalid_argument): F's indices
/// are in [0, map.size()); map has one entry per input vertex and names coarse faces;
/// coarse.from_input has map.size() entries and coarse.to_input is its inverse on the input vertices,
/// which come first; `inserted` matches the coarse vertices with to_input == kInvalid; V is empty or
/// has one row per input vertex. `V` (optional) gives CoarseTracing's length ratios and the input
/// triangles' shapes that choose among a far corner's images (see above); empty: neither.
/// Each edge's trace is independent; threads = 0 uses the hardware's.
CoarseTracing trace_coarse_mesh(const Faces& F, const CompactMesh& coarse, const std::vector<CoarsePoint>& map,
                                const std::vector<InputSurfacePoint>& inserted = {}, const Positions& V = {},
                                int threads = 1);

/// An ICE coarse space traced on its input `mesh`: exactly, pulled back through the triangulation's
/// history, when the space was built with record_history; else trace_coarse_mesh of mesh.F,
/// space.mesh, its fine-to-coarse map, its inserted points and mesh.V (the walk). The length
/// ratios are set either way. Precondition (std::invalid_argument): the space was built with
/// keep_method_state by ICE (a QEM mesh is extrinsic: its edges are straight segments between its
/// positions, nothing to trace).
CoarseTracing trace_coarse_mesh(const TriangleMesh& mesh, const CoarseSpace& space, int threads = 0);

/// The polyline of a traced edge on the input surface (positions of its segments' ends, joined:
/// segments + 1 rows; empty for an edge without segments).
Positions traced_polyline(const Positions& V, const Faces& F, const TracedEdge& edge);

/// Length of that polyline.
double traced_length(const Positions& V, const Faces& F, const TracedEdge& edge);

/// The shortest path between the ends of a traced edge within the input faces it crosses, unfolded
/// into the plane (the funnel algorithm; where the trace passes from one face to the next through
/// a vertex, that point stays on the path): never longer than traced_length, and the surface's
/// geodesic between the ends wherever that runs inside those faces. Gathers F's gluing (O(|F|)) for
/// this one edge; traced_edge_lengths measures them all with one.
double shortest_traced_length(const Positions& V, const Faces& F, const TracedEdge& edge);

/// How traced_edge_lengths measures a traced edge on the input surface.
enum class TracedLengthMeasure {
  polyline,           ///< its polyline's length (traced_length)
  shortest_in_strip,  ///< the shortest path between its ends within the input faces it crosses, unfolded
                      ///< (the funnel algorithm): never longer than the polyline, a geodesic where the
                      ///< strip holds one
};

/// The coarse mesh's edge lengths on the input surface: each traced edge's length by
/// `measure` (on both sides of the edge), where ICE's flattening has changed the metric. An
/// edge that was not traced keeps its intrinsic length, and so do the three edges of a face whose
/// traced lengths break the triangle inequality (and their other sides), so the result is a valid
/// intrinsic metric on `coarse`'s faces. Preconditions: `tracing` traced `coarse` on (V, F);
/// std::invalid_argument otherwise.
FaceLengths traced_edge_lengths(const Positions& V, const Faces& F, const CompactMesh& coarse, const CoarseTracing& tracing,
                                TracedLengthMeasure measure = TracedLengthMeasure::shortest_in_strip);

/// What surface_edge_lengths returns: the lengths, and how many edges the walk traced.
struct SurfaceEdgeLengths {
  FaceLengths lengths;          ///< per coarse face side, as CompactMesh::L
  Index edges = 0, traced = 0;  ///< coarse edges, and those traced (the rest keep their intrinsic lengths)
};

/// The coarse edges' lengths on the input surface, for coarse marching: traced_edge_lengths (shortest
/// in strip) of the walk over the map (trace_coarse_mesh(mesh.F, coarse, map, inserted, mesh.V,
/// threads)), so it needs the fine-to-coarse map, not the coarsening's history. Why the walk and not
/// the exact pull-back: it was measured as accurate for geodesics against exact polyhedral geodesics,
/// and cheaper in time and memory on large meshes (the pull-back is cheaper only on small ones);
/// docs/measurements.md, "Traced lengths for coarse marching". Edges the walk does not trace keep
/// their intrinsic lengths: few on most meshes, up to about half on some, where the geodesics were
/// still nearer exact with the walk than with the exact trace (same section), which is what
/// decided. Preconditions as trace_coarse_mesh's, with mesh.V given (std::invalid_argument).
SurfaceEdgeLengths surface_edge_lengths(const TriangleMesh& mesh, const CompactMesh& coarse, const std::vector<CoarsePoint>& map,
                                        const std::vector<InputSurfacePoint>& inserted = {}, int threads = 0);

}  // namespace ice
