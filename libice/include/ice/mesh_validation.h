#pragma once
/// \file mesh_validation.h
/// Validation of raw polygon input: everything that makes the ICE method undefined or its numbers
/// meaningless is detected, counted and located here, before any half-edge structure is built.
///
/// The input is a `PolygonSoup` (positions + arbitrary index lists), exactly as it came out of the file,
/// so that non-manifold, non-triangle and out-of-range faces are visible. `validate_mesh` never throws
/// on bad input and runs in O(V + C) for C face corners, apart from sorting each vertex's few edges
/// (soups of 100,000 faces or more on up to 8 threads; the report does not depend on their number).
///
/// Definitions used by the report (they match the figures of the mesh sets' tables, data/README.md):
///  - A face is *well formed* if it has >= 3 corners, all indices in [0, V) and no repeated index.
///    Only well-formed faces enter the topological analysis (edges, manifoldness, components, ...).
///  - Edge: an unordered vertex pair {a, b} that is consecutive in some well-formed face.
///    Boundary edge: one incident face. Non-manifold edge: more than two incident faces.
///  - Non-manifold vertex: its incident faces form more than one *fan*, where two faces around v are in
///    the same fan if they are linked through edges at v that have exactly two incident faces
///    (so pinch vertices and the endpoints of non-manifold edges are both reported).
///  - Inconsistently oriented edge: an edge with two incident faces that traverse it in the same
///    direction. A component is non-orientable if no choice of per-face flips makes all its two-face
///    edges consistent (Möbius strip).
///  - Connected components: faces connected through shared vertices; unreferenced vertices are not
///    components. Boundary loops: connected components of the graph of boundary edges.
///  - Euler characteristic χ = V − E + F per component (referenced vertices only); genus
///    g = (2 − χ − b)/2 for b boundary loops, defined only for manifold orientable components.
///  - Zero-area face: twice its area is <= `kDegenerateRelativeTolerance` × (longest edge)² (a
///    translation- and scale-invariant shape test, so coordinates around 1e6 are fine), or its
///    longest edge is <= 1e-14 × the bounding-box diagonal (all corners coincide).
///  - Duplicate faces: faces with the same vertex set as an earlier face (the later copies are counted).
///  - Duplicate positions (information only): vertices whose position equals an earlier vertex exactly.
#include <algorithm>
#include <array>
#include <initializer_list>
#include <iterator>
#include <cstddef>
#include <string>
#include <vector>

#include "ice/mesh.h"

namespace ice {

/// The corner lists of a soup's faces (any length, any values), stored flat: one array of corners
/// and one of offsets. (A vector per face meant 3.2M allocations and a pointer chase per face at
/// 1.6M vertices.) `list[f]` is a view of face f's corners, valid until the list changes.
class PolygonList {
 public:
  /// A view of one face's corners.
  template <class T>
  class Corners {
   public:
    Corners(T* begin, T* end) : begin_(begin), end_(end) {}
    T* begin() const { return begin_; }
    T* end() const { return end_; }
    std::size_t size() const { return static_cast<std::size_t>(end_ - begin_); }
    bool empty() const { return begin_ == end_; }
    T& operator[](std::size_t k) const { return begin_[k]; }
    std::vector<Index> to_vector() const { return std::vector<Index>(begin_, end_); }
    bool operator==(const std::vector<Index>& other) const {
      return size() == other.size() && std::equal(begin_, end_, other.begin());
    }

   private:
    T* begin_;
    T* end_;
  };

  class const_iterator {
   public:
    const_iterator(const PolygonList* list, std::size_t face) : list_(list), face_(face) {}
    Corners<const Index> operator*() const { return (*list_)[face_]; }
    const_iterator& operator++() { return ++face_, *this; }
    bool operator!=(const const_iterator& other) const { return face_ != other.face_; }
    bool operator==(const const_iterator& other) const { return face_ == other.face_; }

   private:
    const PolygonList* list_;
    std::size_t face_;
  };

  PolygonList() = default;
  PolygonList(std::initializer_list<std::initializer_list<Index>> faces) {
    for (const auto& face : faces) push_back(face);
  }
  /// Faces of three corners each from a flat corner array (3f, 3f+1, 3f+2).
  static PolygonList triangles(std::vector<Index> corners) {
    PolygonList list;
    const std::size_t faces = corners.size() / 3;
    list.corners_ = std::move(corners);
    list.corners_.resize(3 * faces);
    list.offsets_.resize(faces + 1);
    for (std::size_t f = 0; f <= faces; ++f) list.offsets_[f] = 3 * f;
    return list;
  }

  std::size_t size() const { return offsets_.size() - 1; }
  bool empty() const { return size() == 0; }
  /// The total number of corners.
  std::size_t corner_count() const { return corners_.size(); }
  Corners<const Index> operator[](std::size_t f) const {
    return {corners_.data() + offsets_[f], corners_.data() + offsets_[f + 1]};
  }
  Corners<Index> operator[](std::size_t f) { return {corners_.data() + offsets_[f], corners_.data() + offsets_[f + 1]}; }
  const_iterator begin() const { return {this, 0}; }
  const_iterator end() const { return {this, size()}; }

  template <class Range>
  void push_back(const Range& corners) {
    corners_.insert(corners_.end(), std::begin(corners), std::end(corners));
    offsets_.push_back(corners_.size());
  }
  void push_back(std::initializer_list<Index> corners) { push_back<std::initializer_list<Index>>(corners); }
  void reserve(std::size_t faces, std::size_t corners) {
    offsets_.reserve(faces + 1);
    corners_.reserve(corners);
  }
  void clear() {
    corners_.clear();
    offsets_.assign(1, 0);
  }
  /// The flat arrays: face f's corners are corners()[offsets()[f] .. offsets()[f+1]).
  const std::vector<Index>& corners() const { return corners_; }
  const std::vector<std::size_t>& offsets() const { return offsets_; }

  bool operator==(const PolygonList& other) const { return corners_ == other.corners_ && offsets_ == other.offsets_; }
  bool operator!=(const PolygonList& other) const { return !(*this == other); }

 private:
  std::vector<Index> corners_;
  std::vector<std::size_t> offsets_{0};
};

/// Raw polygonal input: positions and one index list per face, 0-based, unchecked.
struct PolygonSoup {
  Positions V;           ///< n×3 positions (may contain NaN/inf).
  PolygonList polygons;  ///< Face corner lists (any length, any values).
};

/// Convert a triangle mesh to a soup (for validating meshes built in code).
PolygonSoup to_polygon_soup(const TriangleMesh& mesh);

/// How many offending elements of each kind a report keeps (the count is always exact).
constexpr std::size_t kMaxOffenders = 5;

/// Relative tolerance of the zero-area test: 2·area <= tol · (longest edge)². A triangle whose
/// smallest height is below 1e-10 of its longest edge has angles that cotangent formulas cannot use.
constexpr double kDegenerateRelativeTolerance = 1e-10;

/// An exact count plus the first `kMaxOffenders` offending elements.
template <class T>
struct Offenders {
  std::size_t count = 0;
  std::vector<T> first;
  void add(const T& element) {
    if (first.size() < kMaxOffenders) first.push_back(element);
    ++count;
  }
  bool empty() const { return count == 0; }
};

/// An undirected edge as a vertex pair (smaller index first).
using VertexPair = std::array<int, 2>;

/// Topology of one connected component.
struct ComponentInfo {
  std::size_t n_vertices = 0;        ///< Referenced vertices.
  std::size_t n_edges = 0;
  std::size_t n_faces = 0;           ///< Well-formed faces.
  std::size_t n_boundary_loops = 0;
  long euler_characteristic = 0;     ///< V − E + F.
  bool manifold = true;              ///< No non-manifold edge or vertex.
  bool orientable = true;            ///< Meaningful only if manifold.
  bool consistently_oriented = true; ///< No inconsistently oriented edge.
  int genus = -1;                    ///< (2 − χ − b)/2 if manifold and orientable, else −1.
};

/// Everything `validate_mesh` found. Defects and information are kept apart: `defects()` lists what
/// the ICE loading policy refuses (see mesh_io.h), the rest is description.
struct ValidationReport {
  std::size_t n_vertices = 0;        ///< Vertices in the input, including unreferenced ones.
  std::size_t n_faces = 0;           ///< Faces in the input, including broken ones.
  std::size_t n_edges = 0;           ///< Unique edges of well-formed faces.

  // -- defects: each makes the method undefined --
  Offenders<int> non_triangle_faces;       ///< Face ids with a corner count other than 3 (incl. < 3).
  Offenders<int> out_of_range_faces;       ///< Face ids with an index outside [0, V).
  Offenders<int> repeated_index_faces;     ///< Face ids that list a vertex twice.
  Offenders<int> non_finite_vertices;      ///< Vertex ids with a NaN or infinite coordinate.
  Offenders<int> unreferenced_vertices;    ///< Vertex ids used by no well-formed face.
  Offenders<int> duplicate_faces;          ///< Face ids repeating the vertex set of an earlier face.
  Offenders<int> zero_area_faces;          ///< Well-formed face ids failing the zero-area test.
  Offenders<VertexPair> non_manifold_edges;
  Offenders<int> non_manifold_vertices;
  Offenders<VertexPair> inconsistent_edges;///< Two-face edges traversed twice in the same direction.
  std::size_t non_orientable_components = 0;

  // -- information --
  Offenders<int> duplicate_positions;      ///< Vertex ids whose position repeats an earlier one.
  std::vector<ComponentInfo> components;
  std::size_t n_boundary_loops = 0;
  long euler_characteristic = 0;           ///< Sum over components.
  int genus = -1;                          ///< Sum over components; −1 unless every one is manifold and orientable.
  Eigen::Vector3d bbox_min = Eigen::Vector3d::Zero();  ///< Bounding box of the finite vertices.
  Eigen::Vector3d bbox_max = Eigen::Vector3d::Zero();
  double edge_length_min = 0, edge_length_mean = 0, edge_length_max = 0;  ///< Over unique edges.

  bool manifold() const { return non_manifold_edges.empty() && non_manifold_vertices.empty(); }
  bool orientable() const { return non_orientable_components == 0; }
  /// True if the mesh satisfies every precondition of ICE (no entry in `defects()`).
  bool clean() const { return defects().empty(); }
  /// True if every defect (if any) is one the tufted cover resolves (ice/tufted_cover.h): non-manifold
  /// edges or vertices, inconsistent orientation, non-orientable components.
  bool clean_but_for_sheets() const;
  /// One line per defect kind: "<count> <what> (first: ...)". Empty for a clean mesh.
  std::vector<std::string> defects() const;
};

/// Validate a raw polygon soup. Never throws on bad data; never reads out of range.
ValidationReport validate_mesh(const PolygonSoup& soup);

/// Validate a triangle mesh built in code.
ValidationReport validate_mesh(const TriangleMesh& mesh);

/// The zero-area test of the report (see file comment) for the triangle (a, b, c) of a mesh whose
/// bounding-box diagonal is `diagonal`. Non-finite input counts as degenerate.
bool is_zero_area_triangle(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                           double diagonal);

/// The degenerate-face test of the report (counted as a zero-area face) and of the repair: the
/// triangle (a, b, c) of V is a zero-area triangle, or its edge lengths as face_lengths_from_positions
/// computes them fail the strict triangle inequality (triangle_inequality_holds), which is what
/// IntrinsicTriangulation::from_mesh requires. The second catches slivers the relative area test
/// lets through (an apex 1e-9 of the base's length off the base: its lengths add up exactly), so a
/// mesh the report calls clean always makes a triangulation.
bool is_degenerate_triangle(const Positions& V, int a, int b, int c, double diagonal);

}  // namespace ice
