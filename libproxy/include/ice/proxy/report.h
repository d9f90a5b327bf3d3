#pragma once
/// \file report.h
/// The JSON objects the tools' reports and the Python package share, so that a script reads the same
/// keys as a tool writes: a mesh validation, a coarsening's summary, QEM's details, polishing, a
/// multigrid solve. Enum values are written by their spellings (policies.h).
#include <nlohmann/json.hpp>

#include "fem/coarse_proxy.h"
#include "fem/multigrid.h"
#include "ice/coarse_space.h"
#include "ice/mesh_validation.h"
#include "ice/proxy/multigrid.h"
#include "ice/proxy/store.h"

namespace ice::proxy {

/// A mesh validation report (ice/mesh_validation.h) as `ice-info --json` writes it: sizes, topology,
/// bounding box, edge lengths, each defect's count and first offenders, the components.
nlohmann::json validation_json(const ValidationReport& report);

/// The "coarse" object: vertices, faces, stop_reason, removed (ICE removals or QEM collapses), the
/// refinement if any, and for ICE its removal details (failed removals by status, costs, phase times).
nlohmann::json coarsen_json(const CoarseSpaceSummary& summary);

/// The "qem" object: mapping, collapses, guard, distances, times, the coarse mesh's geometry.
nlohmann::json qem_json(const QemOutcome& qem, bool target_reached);

/// The "polish" object: the options (iteration limit, tolerance, smoother) and what polishing did
/// (iterations, estimated errors, whether the tolerance was reached, seconds).
nlohmann::json polish_json(const fem::PolishOptions& options, const fem::PolishReport& report);

/// A multigrid solver's last solve and set-up (iterations, convergence, residuals, options, levels,
/// operator complexity, seconds).
nlohmann::json multigrid_json(const fem::MultigridSolver& solver);

/// The "hierarchy" object of a multigrid route: the options it was built with (ratio,
/// coarsest_vertices), levels, grid_complexity, stop_reason and coarsen_seconds (of the build that
/// made it: the stored one's on a store hit).
nlohmann::json hierarchy_json(const MultigridHierarchy& hierarchy, const HierarchyOptions& options);

/// The "cache" object: status (off, miss, hit, rebuilt), the store's directory, the entries' keys,
/// the damage found and any error writing an entry. Its times go to "timings_s" (cache_load, cache_save).
nlohmann::json cache_json(const CacheReport& cache, const Store& store);

}  // namespace ice::proxy
