#pragma once
/// \file errors.h
/// Error measures of an approximate solution against a reference on the same (fine) vertices.
#include <Eigen/Core>

#include "fem/operators.h"

namespace fem {

/// Relative error in the mass norm: sqrt((a−r)ᵀM(a−r) / rᵀMr). Preconditions: equal sizes, M the
/// n×n mass matrix, rᵀMr > 0 (throws std::invalid_argument otherwise).
/// Here and below, entries where both vectors are +∞ (distances on a component that no source
/// reaches) are left out; +∞ against a finite value gives an infinite error.
double relative_l2_error(const Eigen::VectorXd& approx, const Eigen::VectorXd& reference, const SparseMatrix& mass);

/// max_i |a_i − r_i|. Precondition: equal, non-zero sizes.
double max_abs_error(const Eigen::VectorXd& approx, const Eigen::VectorXd& reference);

/// Errors of a distance field relative to the largest reference distance D = max_i r_i:
/// mean_relative = (1/n) Σ_i |a_i − r_i| / D (plain vertex average), max_relative = max_i |a_i − r_i| / D.
struct DistanceErrors {
  double mean_relative = 0;
  double max_relative = 0;
};

/// Precondition: equal, non-zero sizes and max_i r_i > 0.
DistanceErrors distance_errors(const Eigen::VectorXd& approx, const Eigen::VectorXd& reference);

}  // namespace fem
