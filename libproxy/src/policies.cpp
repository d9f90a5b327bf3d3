#include "ice/proxy/policies.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "fem/curvature_correction.h"

namespace ice::proxy {

fem::ProlongationKind resolve_prolongation(Prolongation choice, fem::CoarseOperatorKind operators, bool dirichlet,
                                           ProlongationUse use) {
  const bool galerkin = operators == fem::CoarseOperatorKind::galerkin;
  if (choice == Prolongation::smoothed || choice == Prolongation::smoothed_twice) {
    if (!galerkin) throw std::invalid_argument("a smoothed prolongation needs Galerkin coarse operators");
    if (dirichlet)
      throw std::invalid_argument("a smoothed prolongation does not take the fixed values at Dirichlet vertices: "
                                  "use the barycentric one (or 'auto')");
    return choice == Prolongation::smoothed ? fem::ProlongationKind::smoothed : fem::ProlongationKind::smoothed_twice;
  }
  if (choice == Prolongation::automatic && galerkin && !dirichlet)
    return use == ProlongationUse::eigenpairs ? fem::ProlongationKind::smoothed_twice : fem::ProlongationKind::smoothed;
  return fem::ProlongationKind::barycentric;
}

Prolongation prolongation_choice(fem::ProlongationKind kind) {
  switch (kind) {
    case fem::ProlongationKind::smoothed: return Prolongation::smoothed;
    case fem::ProlongationKind::smoothed_twice: return Prolongation::smoothed_twice;
    case fem::ProlongationKind::barycentric: break;
  }
  return Prolongation::barycentric;
}

bool traces_lengths(CoarseLengths choice, CoarseningMethod method, bool marching) {
  return marching && (choice == CoarseLengths::traced || (choice == CoarseLengths::automatic && method == CoarseningMethod::ice));
}

bool corrects_curvature(CurvatureCorrection choice, CoarseningMethod method, bool tufted_cover) {
  return choice == CurvatureCorrection::on ||
         (choice == CurvatureCorrection::automatic && method == CoarseningMethod::ice && !tufted_cover);
}

double curvature_divisor(MarchingUse use) {
  return use == MarchingUse::all_pairs ? fem::kOracleCorrectionDivisor : fem::kProxyCorrectionDivisor;
}

Index target_vertices(Index n, double ratio, Index min_vertices) {
  const auto by_ratio = static_cast<long long>(std::ceil(ratio * static_cast<double>(n)));
  return static_cast<Index>(std::min<long long>(n, std::max<long long>(by_ratio, min_vertices)));
}

CoarseSpaceOptions default_coarsening(ProxyUse use, double ratio) {
  CoarseSpaceOptions options;
  options.coarsen = recommended_coarsen_options(use);
  options.coarsen.target_ratio = ratio;
  return options;
}

template <>
const Spellings<Prolongation>& spellings<Prolongation>() {
  static const Spellings<Prolongation> names{
      {"auto", Prolongation::automatic}, {"barycentric", Prolongation::barycentric}, {"smoothed", Prolongation::smoothed},
      {"smoothed_twice", Prolongation::smoothed_twice}};
  return names;
}
template <>
const Spellings<CoarseLengths>& spellings<CoarseLengths>() {
  static const Spellings<CoarseLengths> names{
      {"auto", CoarseLengths::automatic}, {"intrinsic", CoarseLengths::intrinsic}, {"traced", CoarseLengths::traced}};
  return names;
}
template <>
const Spellings<CurvatureCorrection>& spellings<CurvatureCorrection>() {
  static const Spellings<CurvatureCorrection> names{
      {"auto", CurvatureCorrection::automatic}, {"on", CurvatureCorrection::on}, {"off", CurvatureCorrection::off}};
  return names;
}
template <>
const Spellings<VectorSolver>& spellings<VectorSolver>() {
  static const Spellings<VectorSolver> names{{"sweep", VectorSolver::sweep}, {"diffusion", VectorSolver::diffusion}};
  return names;
}
template <>
const Spellings<CoarseningMethod>& spellings<CoarseningMethod>() {
  static const Spellings<CoarseningMethod> names{{"ice", CoarseningMethod::ice}, {"qem", CoarseningMethod::qem}};
  return names;
}
template <>
const Spellings<QemGeometry>& spellings<QemGeometry>() {
  static const Spellings<QemGeometry> names{{"extrinsic", QemGeometry::extrinsic},
                                            {"idt", QemGeometry::intrinsic_delaunay},
                                            {"intrinsic_delaunay", QemGeometry::intrinsic_delaunay}};
  return names;
}
template <>
const Spellings<FineGeometry>& spellings<FineGeometry>() {
  static const Spellings<FineGeometry> names{{"intrinsic_delaunay", FineGeometry::intrinsic_delaunay},
                                             {"idt", FineGeometry::intrinsic_delaunay},
                                             {"input", FineGeometry::input}};
  return names;
}
template <>
const Spellings<NonmanifoldInput>& spellings<NonmanifoldInput>() {
  static const Spellings<NonmanifoldInput> names{{"refuse", NonmanifoldInput::refuse},
                                                 {"tufted", NonmanifoldInput::tufted_cover}};
  return names;
}
template <>
const Spellings<ProxyUse>& spellings<ProxyUse>() {
  static const Spellings<ProxyUse> names{{"poisson_heat", ProxyUse::poisson_heat}, {"geodesic", ProxyUse::geodesic}};
  return names;
}
template <>
const Spellings<CacheStatus>& spellings<CacheStatus>() {
  static const Spellings<CacheStatus> names{{"off", CacheStatus::off},
                                            {"miss", CacheStatus::miss},
                                            {"hit", CacheStatus::hit},
                                            {"rebuilt", CacheStatus::rebuilt}};
  return names;
}
template <>
const Spellings<fem::CoarseOperatorKind>& spellings<fem::CoarseOperatorKind>() {
  static const Spellings<fem::CoarseOperatorKind> names{{"intrinsic", fem::CoarseOperatorKind::intrinsic},
                                                        {"galerkin", fem::CoarseOperatorKind::galerkin}};
  return names;
}
template <>
const Spellings<fem::VectorOperatorKind>& spellings<fem::VectorOperatorKind>() {
  static const Spellings<fem::VectorOperatorKind> names{{"galerkin", fem::VectorOperatorKind::galerkin},
                                                        {"intrinsic", fem::VectorOperatorKind::intrinsic}};
  return names;
}
template <>
const Spellings<fem::CoarseDistanceMethod>& spellings<fem::CoarseDistanceMethod>() {
  static const Spellings<fem::CoarseDistanceMethod> names{{"marching", fem::CoarseDistanceMethod::marching},
                                                          {"heat", fem::CoarseDistanceMethod::heat_method},
                                                          {"heat_method", fem::CoarseDistanceMethod::heat_method}};
  return names;
}
template <>
const Spellings<fem::ProlongationKind>& spellings<fem::ProlongationKind>() {
  static const Spellings<fem::ProlongationKind> names{{"barycentric", fem::ProlongationKind::barycentric},
                                                      {"smoothed", fem::ProlongationKind::smoothed},
                                                      {"smoothed_twice", fem::ProlongationKind::smoothed_twice}};
  return names;
}

}  // namespace ice::proxy
