#include "ice/tufted_cover.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

#include "cover_copies.h"
#include "disjoint_sets.h"
#include "vertex_buckets.h"
#include "ice/mesh_validation.h"
#include "ice/triangle_geometry.h"

namespace ice {

const char* to_string(NonmanifoldInput choice) {
  return choice == NonmanifoldInput::tufted_cover ? "tufted_cover" : "refuse";
}

bool solved_on_tufted_cover(const TriangleMesh& mesh, NonmanifoldInput choice) {
  return choice == NonmanifoldInput::tufted_cover && needs_tufted_cover(mesh);
}

namespace {

// The sides (3f + k: face f from corner k to k + 1) of F grouped by undirected edge: the sides of
// edge e are sides[start[e] .. start[e + 1]), in increasing side order; low[e] < high[e] its ends.
// Sorted by the smaller end with the triangulation's counting sort (detail::order_by_vertex).
struct EdgeSides {
  std::vector<Index> sides, start, low, high;
};

EdgeSides sides_by_edge(const Faces& F, Index vertex_count) {
  const Index m = static_cast<Index>(F.rows());
  const auto low_of = [&](Index s) { return std::min(F(s / 3, s % 3), F(s / 3, (s % 3 + 1) % 3)); };
  const auto high_of = [&](Index s) { return std::max(F(s / 3, s % 3), F(s / 3, (s % 3 + 1) % 3)); };
  EdgeSides out;
  out.sides = detail::order_by_vertex(static_cast<std::size_t>(3 * m), vertex_count, low_of,
                                      [&](Index a, Index b) { return high_of(a) < high_of(b); });  // stable: ties by side
  for (std::size_t i = 0; i < out.sides.size(); ++i) {
    const Index s = out.sides[i];
    if (i == 0 || low_of(s) != low_of(out.sides[i - 1]) || high_of(s) != high_of(out.sides[i - 1])) {
      out.start.push_back(static_cast<Index>(i));
      out.low.push_back(low_of(s));
      out.high.push_back(high_of(s));
    }
  }
  out.start.push_back(static_cast<Index>(out.sides.size()));
  return out;
}

// The corner of side s's face at the vertex where s ends (side 3f + k runs from corner k to k + 1):
// where a fan continues across s's edge onto s's face, from the other side of that edge.
Index head_corner(Index s) { return 3 * (s / 3) + (s % 3 + 1) % 3; }

void require_faces_in_range(const TriangleMesh& mesh, const char* who) {
  const Index n = static_cast<Index>(mesh.V.rows());
  if (mesh.V.cols() != 3 || mesh.F.cols() != 3) throw std::invalid_argument(std::string(who) + ": V and F must have 3 columns");
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)
    for (int k = 0; k < 3; ++k)
      if (mesh.F(f, k) < 0 || mesh.F(f, k) >= n)
        throw std::invalid_argument(std::string(who) + ": face " + std::to_string(f) + " has a vertex index out of range");
}

}  // namespace

IntrinsicMesh TuftedCover::intrinsic_mesh() const {
  return IntrinsicMesh{mesh.F, face_lengths_from_positions(mesh.V, mesh.F), twin, static_cast<Index>(mesh.V.rows())};
}

bool needs_tufted_cover(const TriangleMesh& mesh) {
  require_faces_in_range(mesh, "needs_tufted_cover");
  const Faces& F = mesh.F;
  const Index n = static_cast<Index>(mesh.V.rows());
  const EdgeSides edges = sides_by_edge(F, n);
  // Corners around a vertex joined across the edges: one class per fan.
  detail::DisjointSets fans(static_cast<std::size_t>(3 * F.rows()));
  for (std::size_t e = 0; e + 1 < edges.start.size(); ++e) {
    const Index count = edges.start[e + 1] - edges.start[e];
    if (count > 2) return true;
    if (count < 2) continue;
    const Index s = edges.sides[static_cast<std::size_t>(edges.start[e])];
    const Index t = edges.sides[static_cast<std::size_t>(edges.start[e]) + 1];
    if (F(s / 3, s % 3) == F(t / 3, t % 3)) return true;  // both run the same way
    // s runs v -> w, t runs w -> v: v is s's corner k and t's corner l + 1; w the other way round.
    fans.unite(static_cast<std::size_t>(s), static_cast<std::size_t>(head_corner(t)));
    fans.unite(static_cast<std::size_t>(t), static_cast<std::size_t>(head_corner(s)));
  }
  std::vector<Index> fan_of(static_cast<std::size_t>(n), kInvalid);
  for (Index c = 0; c < 3 * static_cast<Index>(F.rows()); ++c) {
    const Index v = F(c / 3, c % 3);
    const Index root = static_cast<Index>(fans.find(static_cast<std::size_t>(c)));
    Index& seen = fan_of[static_cast<std::size_t>(v)];
    if (seen == kInvalid) seen = root;
    else if (seen != root) return true;
  }
  return false;
}

TuftedCover tufted_cover(const TriangleMesh& mesh, bool tuft_boundary) {
  require_faces_in_range(mesh, "tufted_cover");
  const Positions& V = mesh.V;
  const Faces& F = mesh.F;
  const Index n = static_cast<Index>(V.rows()), m = static_cast<Index>(F.rows());
  {
    std::vector<char> used(static_cast<std::size_t>(n), 0);
    const double diagonal = n > 0 ? (V.colwise().maxCoeff() - V.colwise().minCoeff()).norm() : 0.0;
    for (Index f = 0; f < m; ++f) {
      if (F(f, 0) == F(f, 1) || F(f, 1) == F(f, 2) || F(f, 0) == F(f, 2))
        throw std::invalid_argument("tufted_cover: face " + std::to_string(f) + " repeats a vertex");
      if (is_degenerate_triangle(V, F(f, 0), F(f, 1), F(f, 2), diagonal))
        throw std::invalid_argument("tufted_cover: face " + std::to_string(f) + " is degenerate (zero area)");
      for (int k = 0; k < 3; ++k) used[static_cast<std::size_t>(F(f, k))] = 1;
    }
    for (Index v = 0; v < n; ++v)
      if (!used[static_cast<std::size_t>(v)])
        throw std::invalid_argument("tufted_cover: vertex " + std::to_string(v) + " lies on no face");
  }
  // Front side s = 3f + k; its back twin runs the other way on face m + f, side 2 − k.
  const auto back = [m](Index s) { return 3 * (m + s / 3) + (2 - s % 3); };
  const EdgeSides edges = sides_by_edge(F, n);
  std::vector<Index> twin(static_cast<std::size_t>(6 * m), kInvalid);
  const auto glue = [&twin](Index a, Index b) {
    twin[static_cast<std::size_t>(a)] = b;
    twin[static_cast<std::size_t>(b)] = a;
  };
  std::vector<std::pair<double, Index>> around;  // (angle about the edge, front side)
  for (std::size_t e = 0; e + 1 < edges.start.size(); ++e) {
    const Index* sides = edges.sides.data() + edges.start[e];
    const Index count = edges.start[e + 1] - edges.start[e];
    const Index lo = edges.low[e], hi = edges.high[e];
    // The sheet of a face that looks towards increasing angle runs lo -> hi along the edge (its
    // normal is u × d, d the face's direction away from the edge): the front when the face itself
    // runs lo -> hi, else the back; the sheet looking the other way runs hi -> lo.
    const auto forward_sheet = [&](Index s) { return F(s / 3, s % 3) == lo ? s : back(s); };
    const auto backward_sheet = [&](Index s) { return F(s / 3, s % 3) == lo ? back(s) : s; };
    if (count == 1) {
      if (tuft_boundary) glue(sides[0], back(sides[0]));  // else both sides stay open
      continue;
    }
    around.clear();
    if (count == 2) {  // two faces: one cyclic order, no angles needed
      around = {{0.0, sides[0]}, {1.0, sides[1]}};
    } else {
      const Eigen::Vector3d u = (V.row(hi) - V.row(lo)).transpose().normalized();
      Eigen::Vector3d e1 = Eigen::Vector3d::Zero(), e2 = Eigen::Vector3d::Zero();
      for (Index i = 0; i < count; ++i) {
        const Index s = sides[i];
        const Index apex = F(s / 3, (s % 3 + 2) % 3);
        Eigen::Vector3d d = (V.row(apex) - V.row(lo)).transpose();
        d -= d.dot(u) * u;
        if (i == 0) {
          e1 = d.normalized();
          e2 = u.cross(e1);
        }
        around.emplace_back(std::atan2(d.dot(e2), d.dot(e1)), s);
      }
      std::sort(around.begin(), around.end());  // ties: by side, i.e. by face
    }
    for (std::size_t i = 0; i < around.size(); ++i)
      glue(forward_sheet(around[i].second), backward_sheet(around[(i + 1) % around.size()].second));
  }
  // Cover faces: front f as given, back m + f with corners 0, 2, 1.
  TuftedCover cover;
  cover.input_vertex_count = n;
  Faces& C = cover.mesh.F;
  C.resize(2 * m, 3);
  for (Index f = 0; f < m; ++f) {
    C.row(f) = F.row(f);
    C(m + f, 0) = F(f, 0);
    C(m + f, 1) = F(f, 2);
    C(m + f, 2) = F(f, 1);
  }
  // Copies: the corners of one vertex joined across every glued side form its fans.
  detail::DisjointSets fans(static_cast<std::size_t>(6 * m));
  for (Index s = 0; s < 6 * m; ++s) {
    const Index t = twin[static_cast<std::size_t>(s)];
    if (t != kInvalid) fans.unite(static_cast<std::size_t>(s), static_cast<std::size_t>(head_corner(t)));
  }
  std::vector<Index> roots;  // a fan's representative is its smallest corner
  for (Index c = 0; c < 6 * m; ++c)
    if (fans.find(static_cast<std::size_t>(c)) == static_cast<std::size_t>(c)) roots.push_back(c);
  const auto input_of = [&C](Index corner) { return C(corner / 3, corner % 3); };
  std::sort(roots.begin(), roots.end(), [&](Index a, Index b) {
    return std::make_pair(input_of(a), a) < std::make_pair(input_of(b), b);
  });
  std::vector<Index> copy_of_root(static_cast<std::size_t>(6 * m), kInvalid);
  cover.to_input.resize(roots.size());
  for (std::size_t i = 0; i < roots.size(); ++i) {
    copy_of_root[static_cast<std::size_t>(roots[i])] = static_cast<Index>(i);
    cover.to_input[i] = input_of(roots[i]);
  }
  for (Index c = 0; c < 6 * m; ++c)
    C(c / 3, c % 3) = copy_of_root[fans.find(static_cast<std::size_t>(c))];
  cover.mesh.V.resize(static_cast<Eigen::Index>(roots.size()), 3);
  for (std::size_t i = 0; i < roots.size(); ++i) cover.mesh.V.row(static_cast<Eigen::Index>(i)) = V.row(cover.to_input[i]);
  cover.twin = std::move(twin);
  return cover;
}

TuftedCover distinct_sheets(const TuftedCover& cover) {
  const Index faces = static_cast<Index>(cover.mesh.F.rows()), m = faces / 2;
  // What the cover's users index without looking (a cover made by hand may break it).
  const auto refuse = [](const std::string& defect) { throw std::invalid_argument("tufted cover: " + defect); };
  if (faces % 2 != 0) refuse("an odd face count (a front and a back sheet per input face)");
  if (cover.twin.size() != static_cast<std::size_t>(3 * faces)) refuse("the gluing does not have 3 sides per face");
  for (Index s = 0; s < 3 * faces; ++s) {
    const Index t = cover.twin[static_cast<std::size_t>(s)];
    if (t == kInvalid) continue;  // open (a cover without boundary tufts)
    if (t < 0 || t >= 3 * faces || t == s || cover.twin[static_cast<std::size_t>(t)] != s)
      refuse("side " + std::to_string(s) + " is not glued to a side glued back to it");
  }
  if (cover.to_input.size() != static_cast<std::size_t>(cover.mesh.V.rows()))
    refuse("to_input does not have one entry per cover vertex");
  std::vector<char> has_copy(static_cast<std::size_t>(std::max<Index>(cover.input_vertex_count, 0)), 0);
  for (Index v : cover.to_input) {
    if (v < 0 || v >= cover.input_vertex_count) refuse("a cover vertex's input vertex is out of range");
    has_copy[static_cast<std::size_t>(v)] = 1;
  }
  if (std::find(has_copy.begin(), has_copy.end(), 0) != has_copy.end()) refuse("an input vertex has no copy");
  detail::DisjointSets parts = detail::glued_faces(cover);
  // A component is a mirror of another when every face's mirror (f <-> m + f) lies in one other
  // component of the same size; the one whose smallest face (its representative) is larger goes.
  std::vector<Index> size(static_cast<std::size_t>(faces), 0), mirror(static_cast<std::size_t>(faces), kInvalid);
  std::vector<char> mirrored(static_cast<std::size_t>(faces), 1);
  for (Index f = 0; f < faces; ++f) ++size[parts.find(static_cast<std::size_t>(f))];
  for (Index f = 0; f < faces; ++f) {
    const std::size_t c = parts.find(static_cast<std::size_t>(f));
    const Index other = static_cast<Index>(parts.find(static_cast<std::size_t>(f < m ? f + m : f - m)));
    if (other == static_cast<Index>(c) || (mirror[c] != kInvalid && mirror[c] != other)) mirrored[c] = 0;
    mirror[c] = other;
  }
  std::vector<char> keep_face(static_cast<std::size_t>(faces), 1);
  bool dropped = false;
  for (Index f = 0; f < faces; ++f) {
    const std::size_t c = parts.find(static_cast<std::size_t>(f));
    const Index other = mirror[c];
    if (mirrored[c] && mirrored[static_cast<std::size_t>(other)] && size[c] == size[static_cast<std::size_t>(other)] &&
        other < static_cast<Index>(c)) {
      keep_face[static_cast<std::size_t>(f)] = 0;
      dropped = true;
    }
  }
  if (!dropped) return cover;
  TuftedCover out;
  out.input_vertex_count = cover.input_vertex_count;
  std::vector<Index> new_face(static_cast<std::size_t>(faces), kInvalid), new_copy(cover.to_input.size(), kInvalid);
  Index kept = 0;
  for (Index f = 0; f < faces; ++f)
    if (keep_face[static_cast<std::size_t>(f)]) new_face[static_cast<std::size_t>(f)] = kept++;
  for (Index f = 0; f < faces; ++f)  // copies in increasing old order: still consecutive per input vertex
    if (keep_face[static_cast<std::size_t>(f)])
      for (int k = 0; k < 3; ++k) new_copy[static_cast<std::size_t>(cover.mesh.F(f, k))] = 0;
  Index copies = 0;
  for (std::size_t c = 0; c < new_copy.size(); ++c)
    if (new_copy[c] == 0) {
      new_copy[c] = copies++;
      out.to_input.push_back(cover.to_input[c]);
    }
  out.mesh.V.resize(copies, 3);
  for (std::size_t c = 0; c < new_copy.size(); ++c)
    if (new_copy[c] != kInvalid) out.mesh.V.row(new_copy[c]) = cover.mesh.V.row(static_cast<Eigen::Index>(c));
  out.mesh.F.resize(kept, 3);
  out.twin.resize(static_cast<std::size_t>(3 * kept));
  for (Index f = 0; f < faces; ++f) {
    const Index g = new_face[static_cast<std::size_t>(f)];
    if (g == kInvalid) continue;
    for (int k = 0; k < 3; ++k) {
      out.mesh.F(g, k) = new_copy[static_cast<std::size_t>(cover.mesh.F(f, k))];
      const Index t = cover.twin[static_cast<std::size_t>(3 * f + k)];  // in the same component: kept
      out.twin[static_cast<std::size_t>(3 * g + k)] = t == kInvalid ? kInvalid : 3 * new_face[static_cast<std::size_t>(t / 3)] + t % 3;
    }
  }
  return out;
}

Eigen::VectorXd cover_vertex_areas(const TuftedCover& cover) {
  return detail::lumped_vertex_areas(cover.mesh.F, face_lengths_from_positions(cover.mesh.V, cover.mesh.F),
                                     static_cast<Index>(cover.mesh.V.rows()));
}

Eigen::SparseMatrix<double> cover_to_input(const TuftedCover& cover, const Eigen::VectorXd& copy_mass) {
  return copies_to_vertices(cover.to_input, cover.input_vertex_count, copy_mass);
}

Eigen::SparseMatrix<double> copies_to_vertices(const std::vector<Index>& vertex_of_copy, Index vertex_count,
                                               const Eigen::VectorXd& copy_mass) {
  const Index copies = static_cast<Index>(vertex_of_copy.size());
  if (copy_mass.size() != copies)
    throw std::invalid_argument("copies_to_vertices: copy_mass has " + std::to_string(copy_mass.size()) + " entries, for " +
                                std::to_string(copies) + " copies");
  Eigen::VectorXd total = Eigen::VectorXd::Zero(vertex_count);
  Eigen::VectorXi count = Eigen::VectorXi::Zero(vertex_count);
  for (Index c = 0; c < copies; ++c) {
    const Index i = vertex_of_copy[static_cast<std::size_t>(c)];
    if (i < 0 || i >= vertex_count) throw std::invalid_argument("copies_to_vertices: a copy's vertex is out of range");
    total(i) += copy_mass(c);
    ++count(i);
  }
  std::vector<Eigen::Triplet<double>> entries;
  entries.reserve(static_cast<std::size_t>(copies));
  for (Index c = 0; c < copies; ++c) {
    const Index i = vertex_of_copy[static_cast<std::size_t>(c)];
    entries.emplace_back(i, c, total(i) > 0 ? copy_mass(c) / total(i) : 1.0 / count(i));
  }
  Eigen::SparseMatrix<double> W(vertex_count, copies);
  W.setFromTriplets(entries.begin(), entries.end());
  return W;
}

namespace detail {

Eigen::SparseMatrix<double> MergedCopies::spread() const {
  std::vector<Eigen::Triplet<double>> ones;
  ones.reserve(unknown.size());
  for (std::size_t c = 0; c < unknown.size(); ++c) ones.emplace_back(static_cast<Index>(c), unknown[c], 1.0);
  Eigen::SparseMatrix<double> S(static_cast<Index>(unknown.size()), static_cast<Index>(to_input.size()));
  S.setFromTriplets(ones.begin(), ones.end());
  return S;
}

DisjointSets glued_faces(const TuftedCover& cover) {
  const auto faces = static_cast<std::size_t>(cover.mesh.F.rows());
  DisjointSets parts(faces);
  for (std::size_t s = 0; s < 3 * faces; ++s)
    if (cover.twin[s] != kInvalid) parts.unite(s / 3, static_cast<std::size_t>(cover.twin[s] / 3));
  return parts;
}

std::vector<Index> sheet_junctions(const TuftedCover& cover) {
  const auto faces = static_cast<std::size_t>(cover.mesh.F.rows());
  DisjointSets parts = glued_faces(cover);
  // A copy is one fan of faces, so all of them lie in one component: any face names it.
  std::vector<std::size_t> part_of_copy(cover.to_input.size(), faces);
  for (std::size_t f = 0; f < faces; ++f)
    for (int k = 0; k < 3; ++k) part_of_copy[static_cast<std::size_t>(cover.mesh.F(static_cast<Eigen::Index>(f), k))] = parts.find(f);
  std::vector<std::size_t> first_part(static_cast<std::size_t>(cover.input_vertex_count), faces);
  std::vector<char> junction(static_cast<std::size_t>(cover.input_vertex_count), 0);
  for (std::size_t c = 0; c < cover.to_input.size(); ++c) {
    const auto v = static_cast<std::size_t>(cover.to_input[c]);
    if (part_of_copy[c] == faces) continue;  // a copy no face uses
    if (first_part[v] == faces) first_part[v] = part_of_copy[c];
    if (first_part[v] != part_of_copy[c]) junction[v] = 1;
  }
  std::vector<Index> junctions;
  for (std::size_t v = 0; v < junction.size(); ++v)
    if (junction[v]) junctions.push_back(static_cast<Index>(v));
  return junctions;
}

MergedCopies merge_copies(const std::vector<Index>& input_of_copy, Index input_vertices) {
  MergedCopies m;
  m.unknown.resize(input_of_copy.size());
  m.from_input.assign(static_cast<std::size_t>(input_vertices), kInvalid);
  for (std::size_t c = 0; c < input_of_copy.size(); ++c) {
    Index& u = m.from_input[static_cast<std::size_t>(input_of_copy[c])];
    if (u == kInvalid) {
      u = static_cast<Index>(m.to_input.size());
      m.to_input.push_back(input_of_copy[c]);
    }
    m.unknown[c] = u;
  }
  return m;
}

std::vector<Index> copies_of(const std::vector<Index>& input_of_copy, Index input_vertices, const std::vector<Index>& vertices) {
  std::vector<char> wanted(static_cast<std::size_t>(input_vertices), 0);
  for (Index v : vertices)
    if (v >= 0 && v < input_vertices) wanted[static_cast<std::size_t>(v)] = 1;
  std::vector<Index> copies;
  for (std::size_t c = 0; c < input_of_copy.size(); ++c)
    if (wanted[static_cast<std::size_t>(input_of_copy[c])]) copies.push_back(static_cast<Index>(c));
  return copies;
}

Eigen::VectorXd lumped_vertex_areas(const Faces& F, const FaceLengths& L, Index vertex_count) {
  Eigen::VectorXd area = Eigen::VectorXd::Zero(vertex_count);
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    const double third = triangle_area(L(f, 0), L(f, 1), L(f, 2)) / 3.0;
    for (int k = 0; k < 3; ++k) area(F(f, k)) += third;
  }
  return area;
}

}  // namespace detail

}  // namespace ice
