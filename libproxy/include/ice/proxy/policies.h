#pragma once
/// \file policies.h
/// The choices a coarse-proxy recipe makes, each defined once with its measured "auto": how values
/// reach the fine vertices (Prolongation), which lengths coarse marching runs on (CoarseLengths),
/// whether they are curvature-corrected and how strongly for which marching (CurvatureCorrection,
/// MarchingUse), how vector fields are found (VectorSolver), and how a vertex ratio becomes a target.
/// The tools, the report and the Python package read these; why each "auto" is what it is, and the
/// figures behind it, are in docs/measurements.md.
///
/// Each enum has one spelling table (spellings<Enum>()): the names the command lines, the Python
/// package and the JSON reports use for its values.
#include <string>
#include <utility>
#include <vector>

#include "fem/cholesky.h"
#include "fem/coarse_proxy.h"
#include "fem/vector_fields.h"
#include "ice/coarse_space.h"
#include "ice/proxy/store.h"

namespace ice::proxy {

/// How coarse values reach the fine vertices.
enum class Prolongation {
  automatic,    ///< smoothed where it is allowed (Galerkin operators, no Dirichlet vertices), else barycentric
  barycentric,  ///< fem::ProlongationKind::barycentric
  smoothed,     ///< fem::ProlongationKind::smoothed
  smoothed_twice,  ///< fem::ProlongationKind::smoothed_twice
};
/// What a proxy's prolongation serves: it decides what Prolongation::automatic means where smoothing
/// is allowed.
enum class ProlongationUse {
  solves,      ///< Poisson and heat solves: smoothed once (docs/measurements.md, "Smoothed prolongation")
  eigenpairs,  ///< the eigenbasis: smoothed twice, the more accurate eigenpairs for a denser P
               ///< (docs/measurements.md, "The eigenbasis through P smoothed twice")
};
/// The prolongation `choice` means for coarse operators of `operators`, a problem with (`dirichlet`)
/// or without Dirichlet vertices, and `use`. Throws std::invalid_argument for `smoothed` or
/// `smoothed_twice` with intrinsic operators or with Dirichlet vertices (a smoothed P does not take
/// the fixed values at the fixed vertices).
fem::ProlongationKind resolve_prolongation(Prolongation choice, fem::CoarseOperatorKind operators, bool dirichlet,
                                           ProlongationUse use = ProlongationUse::solves);
/// The explicit choice that resolves to `kind` (a resolved prolongation handed on as a choice).
Prolongation prolongation_choice(fem::ProlongationKind kind);

/// Which coarse edge lengths coarse marching runs on.
enum class CoarseLengths {
  automatic,  ///< traced for ICE coarse meshes, their own for QEM's
  intrinsic,  ///< the coarse mesh's own lengths
  traced,     ///< the coarse edges traced on the input surface (ICE only)
};
/// Whether a coarse space made by `method` is marched on traced lengths under `choice`; never when
/// the coarse distances do not come from marching (`marching` false).
bool traces_lengths(CoarseLengths choice, CoarseningMethod method, bool marching);

/// Whether coarse marching runs on curvature-corrected lengths (fem/curvature_correction.h).
enum class CurvatureCorrection {
  /// for ICE coarse meshes, not for QEM's (whose chords already offset the flat faces' bias), nor on a
  /// tufted cover (the curvature is gathered from the input's faces around each vertex, several
  /// sheets' fans where sheets meet: not the surface's angle defect; docs/measurements.md, "Coarse
  /// marching on the cover")
  automatic,
  on,
  off,
};
/// Whether `choice` corrects marching on a coarse space made by `method` (of a tufted cover or not).
bool corrects_curvature(CurvatureCorrection choice, CoarseningMethod method, bool tufted_cover = false);

/// Which marching reads corrected lengths: each has the divisor measured for it.
enum class MarchingUse {
  single_source,  ///< distances from sources (fem::ProxyGeodesicSolver): fem::kProxyCorrectionDivisor
  all_pairs,      ///< the distance oracle (fem::DistanceOracle): fem::kOracleCorrectionDivisor
};
/// The curvature correction's divisor d of exp(K l²/d) for `use`.
double curvature_divisor(MarchingUse use);

/// How vector fields are found through a coarse space.
enum class VectorSolver {
  sweep,      ///< the coarse marching distance and the fine connection (fem::VectorSweepProxy): the default
  diffusion,  ///< vectors diffused on the coarse mesh and prolonged (fem::VectorHeatProxy)
};

/// The vertex target of `ratio` (0 < ratio <= 1) of n vertices: ceil(ratio·n) as ice::coarsen rounds,
/// raised to `min_vertices` and capped at n. Precondition: n >= 1.
Index target_vertices(Index n, double ratio, Index min_vertices = 0);

/// The coarse space options of a recipe for `use`: ice::recommended_coarsen_options(use) with
/// `ratio` of the input's vertices as the target, by ICE.
CoarseSpaceOptions default_coarsening(ProxyUse use, double ratio = 0.05);

/// The fill-reducing ordering of the fine solves the tools compare the proxy with (their reference):
/// AMD alone, the fastest measured here — as fast as CHOLMOD's default strategy up to 396k vertices
/// and faster at 1.6M, where that strategy also tries METIS — while the BLAS thread count made no
/// measurable difference at any size (docs/measurements.md, "The fine reference").
constexpr fem::CholeskyOrdering kFineReferenceOrdering = fem::CholeskyOrdering::amd;

/// The names of an enum's values, in one table per enum; the first name of a value is its spelling,
/// later ones are accepted aliases.
template <class Enum>
using Spellings = std::vector<std::pair<std::string, Enum>>;
template <class Enum>
const Spellings<Enum>& spellings();
template <> const Spellings<Prolongation>& spellings<Prolongation>();
template <> const Spellings<CoarseLengths>& spellings<CoarseLengths>();
template <> const Spellings<CurvatureCorrection>& spellings<CurvatureCorrection>();
template <> const Spellings<VectorSolver>& spellings<VectorSolver>();
template <> const Spellings<CoarseningMethod>& spellings<CoarseningMethod>();
template <> const Spellings<QemGeometry>& spellings<QemGeometry>();
template <> const Spellings<FineGeometry>& spellings<FineGeometry>();
template <> const Spellings<NonmanifoldInput>& spellings<NonmanifoldInput>();
template <> const Spellings<ProxyUse>& spellings<ProxyUse>();
template <> const Spellings<fem::CoarseOperatorKind>& spellings<fem::CoarseOperatorKind>();
template <> const Spellings<fem::VectorOperatorKind>& spellings<fem::VectorOperatorKind>();
template <> const Spellings<fem::CoarseDistanceMethod>& spellings<fem::CoarseDistanceMethod>();
template <> const Spellings<fem::ProlongationKind>& spellings<fem::ProlongationKind>();
template <> const Spellings<CacheStatus>& spellings<CacheStatus>();

/// The spelling of `value` (its first name in spellings<Enum>()).
template <class Enum>
std::string spelling(Enum value) {
  for (const auto& [name, entry] : spellings<Enum>())
    if (entry == value) return name;
  return "?";
}
/// The names a user may write for Enum's values (the spellings, without aliases), comma-separated.
template <class Enum>
std::string choices() {
  std::string out;
  std::vector<Enum> seen;
  for (const auto& [name, entry] : spellings<Enum>()) {
    bool repeated = false;
    for (Enum s : seen) repeated = repeated || s == entry;
    if (repeated) continue;
    seen.push_back(entry);
    out += (out.empty() ? "'" : ", '") + name + "'";
  }
  return out;
}
/// The value named `text` (a spelling or an alias). Throws std::invalid_argument naming `what` and
/// the choices otherwise.
template <class Enum>
Enum parse(const std::string& text, const std::string& what) {
  for (const auto& [name, entry] : spellings<Enum>())
    if (name == text) return entry;
  throw std::invalid_argument(what + " must be one of " + choices<Enum>() + ", not '" + text + "'");
}

}  // namespace ice::proxy
