#include "stored_space.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>

#include "entry_checks.h"

namespace ice::proxy::detail {

namespace {

// Every field of a CoarseSpaceSummary, in one order for both directions: `field` is called with a
// reference to each (doubles, Index, bool, enums) and the presence flags of its optional parts.
template <class Field>
void visit_summary(CoarseSpaceSummary& s, Field&& field) {
  field(s.method);
  field(s.input_vertices);
  field(s.coarse_vertices);
  field(s.coarse_faces);
  field(s.target_reached);
  field(s.seconds);
  field(s.triangulation_seconds);
  field(s.prolongation_seconds);
  field(s.refinement_seconds);
  bool has_ice = s.ice.has_value(), has_qem = s.qem.has_value(), has_refinement = s.refinement.has_value();
  field(has_ice);
  field(has_qem);
  field(has_refinement);
  if (has_ice) {
    if (!s.ice) s.ice.emplace();
    CoarsenResult& r = *s.ice;
    field(r.stop_reason);
    field(r.input_vertices);
    field(r.output_vertices);
    field(r.output_faces);
    field(r.removed);
    field(r.failed_removals);
    for (Index& count : r.failures_by_status) field(count);
    field(r.last_cost);
    field(r.max_cost);
    field(r.next_cost);
    field(r.parallel_removed);
    field(r.cost_evaluations);
    field(r.seconds);
    field(r.setup_seconds);
    field(r.parallel_seconds);
    field(r.serial_seconds);
  }
  if (has_qem) {
    if (!s.qem) s.qem.emplace();
    QemOutcome& q = *s.qem;
    field(q.collapses);
    field(q.guard_relaxed);
    field(q.max_distance);
    field(q.mean_distance);
    field(q.decimate_seconds);
    field(q.map_seconds);
    field(q.geometry);
    field(q.intrinsic_delaunay_flips);
  }
  if (has_refinement) {
    if (!s.refinement) s.refinement.emplace();
    RefinementResult& r = *s.refinement;
    field(r.inserted);
    field(r.boundary_splits);
    field(r.flips);
    field(r.min_angle_before);
    field(r.min_angle_after);
    field(r.faces_below_bound);
    field(r.sharp_vertex_faces);
    field(r.tiny_faces);
    field(r.bound_reached);
    field(r.budget_exhausted);
  }
}

// Doubles hold every field exactly (counts are below 2^53).
std::vector<double> summary_values(CoarseSpaceSummary summary) {
  std::vector<double> values;
  visit_summary(summary, [&values](auto& f) { values.push_back(static_cast<double>(f)); });
  return values;
}

CoarseSpaceSummary summary_from(const std::vector<double>& values, const std::string& path) {
  CoarseSpaceSummary summary;
  std::size_t next = 0;
  visit_summary(summary, [&](auto& f) {
    if (next >= values.size()) throw std::runtime_error(path + ": the coarse space summary is cut off");
    using T = std::remove_reference_t<decltype(f)>;
    const double v = values[next++];
    if constexpr (!std::is_floating_point_v<T>)
      if (!(v == std::floor(v) && std::abs(v) < 2147483648.0))
        throw std::runtime_error(path + ": the coarse space summary has a count that is not an integer");
    f = static_cast<T>(v);
  });
  if (next != values.size()) throw std::runtime_error(path + ": the coarse space summary has extra values");
  return summary;
}

static_assert(std::is_same_v<Index, std::int32_t>, "vertex maps and gluing are stored as int32 arrays as they are");

}  // namespace

CoarseSpaceArrays::CoarseSpaceArrays(EntryWriter& w, const CoarseSpace& coarse) {
  w.put_int("input_vertices", coarse.P.rows());
  w.put_matrix("coarse.F", coarse.mesh.F);
  w.put_matrix("coarse.L", coarse.mesh.L);
  const std::vector<Index>&twin = coarse.mesh.twin, &to_input = coarse.mesh.to_input, &from_input = coarse.mesh.from_input;
  w.put("coarse.twin", twin.data(), twin.size());
  w.put("coarse.to_input", to_input.data(), to_input.size());
  w.put("coarse.from_input", from_input.data(), from_input.size());
  for (const InputSurfacePoint& p : coarse.inserted) {
    inserted_faces_.push_back(p.face);
    inserted_bary_.insert(inserted_bary_.end(), p.bary.begin(), p.bary.end());
  }
  w.put("coarse.inserted.face", inserted_faces_.data(), inserted_faces_.size());
  w.put("coarse.inserted.bary", inserted_bary_.data(), inserted_bary_.size());
  if (!coarse.P.isCompressed()) {
    compressed_P_ = coarse.P;
    compressed_P_.makeCompressed();
  }
  w.put_sparse("coarse.P", coarse.P.isCompressed() ? coarse.P : compressed_P_);
  summary_ = summary_values(coarse.summary);
  w.put("coarse.summary", summary_.data(), summary_.size());
  // Only where set: entries without it (all made before covers were stored) read as not covered.
  if (coarse.summary.tufted_cover) w.put_int("coarse.tufted_cover", 1);
}

CoarseSpace coarse_space_from_entry(const EntryReader& entry, const std::string& path, const TriangleMesh& mesh) {
    CoarseSpace c;
    const auto n = static_cast<Index>(mesh.V.rows());
    require(entry.integer("input_vertices") == n, path, "made for a mesh of another vertex count");
    std::vector<std::int32_t> to_input = entry.ints("coarse.to_input");
    const auto nc = static_cast<Index>(to_input.size());
    c.mesh.F = entry.int_matrix("coarse.F", 0, nc - 1);
    c.mesh.L = entry.double_matrix("coarse.L");
    require(c.mesh.F.cols() == 3 && c.mesh.L.rows() == c.mesh.F.rows() && c.mesh.L.cols() == 3, path,
            "coarse faces and lengths disagree");
    for (Eigen::Index f = 0; f < c.mesh.L.rows(); ++f) {
      const double a = c.mesh.L(f, 0), b = c.mesh.L(f, 1), d = c.mesh.L(f, 2);
      if (!(a > 0 && b > 0 && d > 0 && a <= b + d && b <= a + d && d <= a + b))
        detail::fail(path, "coarse face " + std::to_string(f) + " breaks the triangle inequality");
    }
    std::vector<std::int32_t> twin = entry.ints("coarse.twin"), from_input = entry.ints("coarse.from_input");
    const auto sides = static_cast<std::int32_t>(3 * c.mesh.F.rows());
    require(twin.empty() || static_cast<Index>(twin.size()) == sides, path, "coarse gluing of the wrong size");
    for (std::int32_t t : twin) require(t >= kInvalid && t < sides, path, "coarse gluing out of range");
    for (std::int32_t v : to_input) require(v >= kInvalid && v < n, path, "coarse vertex map out of range");
    require(static_cast<Index>(from_input.size()) == n, path, "input vertex map of the wrong size");
    for (std::int32_t v : from_input) require(v >= kInvalid && v < nc, path, "input vertex map out of range");
    for (std::size_t side = 0; side < twin.size(); ++side)  // the gluing pairs sides both ways
      require(twin[side] == kInvalid || twin[static_cast<std::size_t>(twin[side])] == static_cast<std::int32_t>(side), path,
              "coarse gluing is not symmetric");
    Index inserted_count = 0;
    for (std::size_t v = 0; v < to_input.size(); ++v) {
      if (to_input[v] == kInvalid) {
        ++inserted_count;
        continue;
      }
      require(from_input[static_cast<std::size_t>(to_input[v])] == static_cast<std::int32_t>(v), path,
              "coarse and input vertex maps disagree");
    }
    for (std::size_t i = 0; i < from_input.size(); ++i)
      require(from_input[i] == kInvalid || to_input[static_cast<std::size_t>(from_input[i])] == static_cast<std::int32_t>(i), path,
              "input and coarse vertex maps disagree");
    c.mesh.twin = std::move(twin);
    c.mesh.to_input = std::move(to_input);
    c.mesh.vertex_count = static_cast<Index>(c.mesh.to_input.size());
    c.mesh.from_input = std::move(from_input);
    const std::vector<std::int32_t> inserted_faces = entry.ints("coarse.inserted.face");
    const std::vector<double> inserted_bary = entry.doubles("coarse.inserted.bary");
    require(inserted_bary.size() == 3 * inserted_faces.size() && static_cast<Index>(inserted_faces.size()) == inserted_count, path,
            "inserted vertices disagree");
    for (double b : inserted_bary) require(std::isfinite(b), path, "an inserted vertex's place is not finite");
    for (std::size_t i = 0; i < inserted_faces.size(); ++i) {
      require(inserted_faces[i] >= 0 && inserted_faces[i] < mesh.F.rows(), path, "inserted vertex in no input face");
      c.inserted.push_back({inserted_faces[i], {inserted_bary[3 * i], inserted_bary[3 * i + 1], inserted_bary[3 * i + 2]}});
    }
    entry.sparse("coarse.P").swap(c.P);  // Eigen 3.4's sparse assignment from a temporary copies; a swap does not
    require(c.P.rows() == n && c.P.cols() == nc, path, "P of the wrong shape");
    c.summary = summary_from(entry.doubles("coarse.summary"), path);
    if (entry.has("coarse.tufted_cover")) {
      require(entry.integer("coarse.tufted_cover") == 1, path, "the tufted-cover mark is not 1");
      c.summary.tufted_cover = true;
    }

    return c;
}

void add_mesh_and_coarsening(KeyHasher& h, const TriangleMesh& mesh, const CoarseSpaceOptions& coarsening) {
  h.add_matrix(mesh.V).add_matrix(mesh.F);
  const CoarsenOptions& c = coarsening.coarsen;
  h.add(to_string(coarsening.method)).add(static_cast<std::int64_t>(c.target_vertices)).add(c.target_ratio);
  h.add(c.max_error).add(c.area_weight).add(c.normalize_curvature).add(c.remove_boundary);
  std::vector<Index> locked = c.locked_vertices;  // a set: order and repeats do not change the result
  std::sort(locked.begin(), locked.end());
  locked.erase(std::unique(locked.begin(), locked.end()), locked.end());
  h.add_bytes(locked.data(), locked.size() * sizeof(Index));
  // The coarsening's result depends on its region count (0 stands for the default count): key on the
  // count it runs with, so a change of the default is a new key.
  h.add(coarsening_regions(c)).add(static_cast<std::int64_t>(c.parallel_min_vertices));
  h.add(to_string(coarsening.qem_geometry)).add(coarsening.locality_numbering);
  h.add(coarsening.refinement.has_value());
  if (coarsening.refinement) h.add(coarsening.refinement->min_angle_degrees).add(coarsening.refinement->max_vertex_ratio);
  // Through the tufted cover: keyed only where the mesh needs it (an oriented manifold's space is the
  // same with either choice, and keeps the key it had before covers were stored).
  // ("sheet junctions locked": covered spaces stored before those were locked are not reused.)
  if (solved_on_tufted_cover(mesh, coarsening.nonmanifold)) h.add(to_string(coarsening.nonmanifold)).add("sheet junctions locked");
}

}  // namespace ice::proxy::detail
