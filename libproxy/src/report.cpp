#include "ice/proxy/report.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "ice/proxy/policies.h"

namespace ice::proxy {

namespace {
template <class T>
nlohmann::json offenders_json(const Offenders<T>& o) {
  return {{"count", o.count}, {"first", o.first}};
}
}  // namespace

nlohmann::json polish_json(const fem::PolishOptions& options, const fem::PolishReport& report) {
  return {{"iterations_limit", options.iterations},
          {"tolerance", options.tolerance},
          {"iterations", report.iterations},
          {"initial_estimated_error", report.initial_estimated_error},
          {"estimated_error", report.estimated_error},
          {"error_estimates", report.error_estimates},
          {"reached_tolerance", report.reached_tolerance},
          {"smoother", fem::to_string(options.cycle.smoother)},
          {"smoothing_steps", options.cycle.smoothing_steps},
          {"seconds", report.seconds}};
}

nlohmann::json multigrid_json(const fem::MultigridSolver& solver) {
  const fem::MultigridReport& r = solver.report();
  const fem::MultigridOptions& options = solver.options();
  nlohmann::json levels = nlohmann::json::array();
  for (const auto& info : solver.level_info()) levels.push_back({{"unknowns", info.unknowns}, {"nonzeros", info.nonzeros}});
  return {{"iterations", r.iterations},
          {"converged", r.converged},
          {"convergence_factor", r.convergence_factor},
          {"relative_residual", r.relative_residual},
          {"tolerance", options.tolerance},
          {"residuals", r.residuals},
          {"seconds", r.seconds},
          {"cycle", fem::to_string(options.mode)},
          {"smoother", fem::to_string(options.smoother)},
          {"threads", options.threads},
          {"reorder", options.reorder},
          {"levels", levels},
          {"operator_complexity", solver.operator_complexity()},
          {"setup_seconds", solver.setup_seconds()}};
}

nlohmann::json validation_json(const ValidationReport& r) {
  nlohmann::json j;
  j["vertices"] = r.n_vertices;
  j["faces"] = r.n_faces;
  j["edges"] = r.n_edges;
  j["clean"] = r.clean();
  j["manifold"] = r.manifold();
  j["orientable"] = r.orientable();
  j["components"] = r.components.size();
  j["boundary_loops"] = r.n_boundary_loops;
  j["euler_characteristic"] = r.euler_characteristic;
  j["genus"] = r.genus >= 0 ? nlohmann::json(r.genus) : nlohmann::json(nullptr);
  j["bbox"] = {{"min", {r.bbox_min.x(), r.bbox_min.y(), r.bbox_min.z()}},
               {"max", {r.bbox_max.x(), r.bbox_max.y(), r.bbox_max.z()}}};
  j["edge_length"] = {{"min", r.edge_length_min}, {"mean", r.edge_length_mean}, {"max", r.edge_length_max}};
  j["defects"] = {
      {"non_triangle_faces", offenders_json(r.non_triangle_faces)},
      {"out_of_range_faces", offenders_json(r.out_of_range_faces)},
      {"repeated_index_faces", offenders_json(r.repeated_index_faces)},
      {"non_finite_vertices", offenders_json(r.non_finite_vertices)},
      {"unreferenced_vertices", offenders_json(r.unreferenced_vertices)},
      {"duplicate_faces", offenders_json(r.duplicate_faces)},
      {"zero_area_faces", offenders_json(r.zero_area_faces)},
      {"non_manifold_edges", offenders_json(r.non_manifold_edges)},
      {"non_manifold_vertices", offenders_json(r.non_manifold_vertices)},
      {"inconsistent_edges", offenders_json(r.inconsistent_edges)},
      {"non_orientable_components", r.non_orientable_components},
  };
  j["duplicate_positions"] = offenders_json(r.duplicate_positions);
  nlohmann::json comps = nlohmann::json::array();
  for (const auto& c : r.components)
    comps.push_back({{"vertices", c.n_vertices}, {"edges", c.n_edges}, {"faces", c.n_faces},
                     {"boundary_loops", c.n_boundary_loops}, {"euler_characteristic", c.euler_characteristic},
                     {"manifold", c.manifold}, {"orientable", c.orientable},
                     {"genus", c.genus >= 0 ? nlohmann::json(c.genus) : nlohmann::json(nullptr)}});
  j["component_list"] = comps;
  return j;
}

nlohmann::json coarsen_json(const CoarseSpaceSummary& summary) {
  nlohmann::json j = {{"vertices", summary.coarse_vertices},
                      {"faces", summary.coarse_faces},
                      {"stop_reason", to_string(summary.stop_reason())},
                      {"removed", summary.removed()}};
  if (summary.tufted_cover) j["tufted_cover"] = true;  // coarsened through the input's tufted cover
  if (summary.refinement) {
    const RefinementResult& r = *summary.refinement;
    j["refinement"] = {{"inserted", r.inserted},
                       {"boundary_splits", r.boundary_splits},
                       {"flips", r.flips},
                       {"min_angle_before_deg", r.min_angle_before},
                       {"min_angle_after_deg", r.min_angle_after},
                       {"faces_below_bound", r.faces_below_bound},
                       {"sharp_vertex_faces", r.sharp_vertex_faces},
                       {"tiny_faces", r.tiny_faces},
                       {"bound_reached", r.bound_reached},
                       {"budget_exhausted", r.budget_exhausted},
                       {"seconds", summary.refinement_seconds}};
  }
  if (!summary.ice) return j;
  const CoarsenResult& result = *summary.ice;
  nlohmann::json failures = nlohmann::json::object();
  for (int s = 0; s < static_cast<int>(result.failures_by_status.size()); ++s)
    if (result.failures_by_status[s] > 0) {
      std::string key = to_string(static_cast<RemovalStatus>(s));
      std::replace(key.begin(), key.end(), ' ', '_');
      failures[key] = result.failures_by_status[s];
    }
  j["failed_removals"] = result.failed_removals;
  j["failures_by_status"] = failures;
  j["last_cost"] = result.last_cost;
  j["max_cost"] = result.max_cost;
  j["next_cost"] = std::isfinite(result.next_cost) ? nlohmann::json(result.next_cost) : nlohmann::json(nullptr);
  j["parallel_removed"] = result.parallel_removed;
  j["cost_evaluations"] = result.cost_evaluations;
  j["phase_seconds"] = {{"triangulation", summary.triangulation_seconds},
                        {"setup", result.setup_seconds},
                        {"parallel", result.parallel_seconds},
                        {"serial", result.serial_seconds},
                        {"prolongation", summary.prolongation_seconds}};
  return j;
}

nlohmann::json qem_json(const QemOutcome& qem, bool target_reached) {
  return {{"mapping", "closest point on the coarse mesh (AABB tree), survivors exact"},
          {"collapses", qem.collapses},
          {"target_reached", target_reached},
          {"normal_guard_relaxed", qem.guard_relaxed},
          {"max_distance", qem.max_distance},
          {"mean_distance", qem.mean_distance},
          {"decimate_s", qem.decimate_seconds},
          {"map_s", qem.map_seconds},
          {"operators", spelling(qem.geometry)},
          {"idt_flips", qem.intrinsic_delaunay_flips}};
}

nlohmann::json hierarchy_json(const MultigridHierarchy& hierarchy, const HierarchyOptions& options) {
  return {{"ratio", options.ratio},
          {"coarsest_vertices", options.coarsest_vertices},
          {"levels", hierarchy.num_levels()},
          {"grid_complexity", hierarchy.grid_complexity()},
          {"stop_reason", hierarchy.stop_reason},
          {"coarsen_seconds", hierarchy.coarsen_seconds}};
}

nlohmann::json cache_json(const CacheReport& cache, const Store& store) {
  nlohmann::json j = {{"status", spelling(cache.status)}, {"keys", cache.keys}};
  j["directory"] = store.enabled() ? nlohmann::json(store.options().directory.string()) : nlohmann::json();
  if (!cache.damage.empty()) j["damage"] = cache.damage;
  if (!cache.save_error.empty()) j["save_error"] = cache.save_error;
  return j;
}

}  // namespace ice::proxy
