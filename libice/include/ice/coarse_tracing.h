#pragma once
/// \file coarse_tracing.h
/// The coarse mesh drawn on the input surface: every coarse (intrinsic) edge traced as a polyline
/// across the input triangles, and every input face labelled by the coarse face that contains it.
///
///   const ice::CoarseSpace space = ice::build_coarse_space(mesh, options);   // keep_method_state
///   const ice::CoarseTracing tracing = ice::trace_coarse_mesh(mesh, space);
///   for (const ice::TracedEdge& e : tracing.edges) draw(ice::traced_polyline(mesh.V, mesh.F, e));
///
/// How: the fine-to-coarse map places every input vertex in a coarse face (barycentric coordinates),
/// so every input triangle has an image in the coarse metric: the triangle spanned by its vertices'
/// images, laid out in one plane by unfolding the coarse faces between them (the coarse metric is
/// flat away from coarse vertices). On the project's test meshes ICE's map does not fold these
/// images (tested on the triangles inside one coarse face or two sharing a side; but see Limits). A
/// coarse edge is a straight segment in the layout
/// of its face; the trace walks that segment across the images of the input triangles, each
/// crossing read back on the input triangle through the same barycentric coordinates. Input
/// vertices near the edge are laid out in the stars of its two end vertices, unfolded about each end
/// and cut opposite the edge (one image per vertex, however curved the cone); vertices further away
/// (input triangles long against coarse faces) by a search over unfoldings that pass through the
/// triangle's image. A boundary edge is the input's boundary chain between its ends.
///
/// Properties (tests/test_coarse_tracing.cpp, on procedural meshes, the project's and the extended
/// set's): a traced edge runs from its tail to its head through segments inside single input faces
/// that join end to end, its positions along the edge increase from 0 to its intrinsic length, two
/// traced edges meet only at coarse vertices (checked here too: edges that cross are marked
/// `crossed`). Where the coarse metric is the input's (an intrinsic Delaunay retriangulation of the
/// input, or ICE on a flat mesh, whose removals flatten nothing) the polyline's length on the input
/// surface equals the intrinsic edge length to round-off; on a coarsened curved mesh the two differ
/// by the metric distortion of ICE's flattening (CoarseTracing::length_ratio_*).
///
/// A far corner has several candidate images (unfoldings around coarse vertices). Only those on the
/// left of the side the walk entered through count (the map does not fold input triangles); with
/// positions given, the walk takes the one whose distances to the entry side's ends, relative to that
/// side, are nearest the input triangle's (ICE's map is close to conformal on a small triangle, and
/// an image in a wrong copy is turned about a coarse vertex by its angle defect); without, the one
/// nearest the entry point.
///
/// Limits (measured 2026-11-27; an edge that cannot be traced is reported, never drawn wrong, with the
/// exception below): of the edges of ICE coarse meshes at 5 % and 1 % of the project's and the shared
/// meshes (`ice-coarsen MESH --ratio R --repair --trace`), 1,529 of 152,932 fail (1.0 %), none on
/// smooth meshes at 5 %; the failures gather where input triangles are long against coarse faces
/// (CAD slivers: boxpart fails most of its edges; elephant-with-holes' thin parts, 11 %; the largest
/// scans, up to 5 % at 1 %), where the layout of a far corner is not resolved. Where the metric is
/// the input's, a wrong layout shows in the length: on the intrinsic Delaunay retriangulations of
/// the 27 shared meshes under 200k vertices, 448 of 820,179 edges are untraced and 199 traced ones
/// differ from their intrinsic length by more than 1e-9 (94 by more than 1e-6, at most 2.9 %, on CAD
/// slivers and scans: camelhead, scan_test1_vcg, boxpart): wrong layouts that the checks above do not
/// catch (1,188 before the shape criterion; mech-holes-shark's went from 87 to 1).
/// Why, where the coarse mesh is ICE's: its map is piecewise affine on the triangulations the
/// coarsening went through (each flattening, flip and merge moves a face's points affinely), not on
/// input triangles, so an input triangle that is large against the coarse faces is bent by it, and
/// the straight triangle between its corners' images can invert. Counted at 5 % (all three corners
/// inside one coarse face with three distinct vertices, so the layout is unambiguous; 2026-11-27):
/// cow 9 of 1,950 such triangles inverted, boxpart 3 of 71, scan_test1_vcg 1 of 12,660; none on
/// camelhead, bunny_zipper_holes, face_scan (nor bear, spot, lion-head: the test). The walk's model
/// fails there; tracing those edges exactly needs the input edges carried through every flattening,
/// flip and removal (a common subdivision kept by the coarsener), which this project does not keep.
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

/// An ICE coarse space traced on its input `mesh`: trace_coarse_mesh of mesh.F, space.mesh, its
/// fine-to-coarse map, its inserted points and mesh.V (length ratios measured). Precondition
/// (std::invalid_argument): the space was built with keep_method_state by ICE (a QEM mesh is
/// extrinsic: its edges are straight segments between its positions, nothing to trace).
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

/// The coarse mesh's edge lengths measured on the input surface: each traced edge's length by
/// `measure` (on both sides of the edge), where ICE's flattening has changed the metric. An
/// edge that was not traced keeps its intrinsic length, and so do the three edges of a face whose
/// traced lengths break the triangle inequality (and their other sides), so the result is a valid
/// intrinsic metric on `coarse`'s faces. Preconditions: `tracing` traced `coarse` on (V, F);
/// std::invalid_argument otherwise.
FaceLengths traced_edge_lengths(const Positions& V, const Faces& F, const CompactMesh& coarse, const CoarseTracing& tracing,
                                TracedLengthMeasure measure = TracedLengthMeasure::shortest_in_strip);

}  // namespace ice
