#include "fem/errors.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace fem {
namespace {

void require_same_size(const Eigen::VectorXd& a, const Eigen::VectorXd& r, const char* what) {
  if (a.size() != r.size() || a.size() == 0)
    throw std::invalid_argument(std::string(what) + ": vectors must be non-empty and of equal size");
}

}  // namespace

double relative_l2_error(const Eigen::VectorXd& approx, const Eigen::VectorXd& reference, const SparseMatrix& mass) {
  require_same_size(approx, reference, "relative_l2_error");
  if (mass.rows() != reference.size() || mass.cols() != reference.size())
    throw std::invalid_argument("relative_l2_error: mass matrix size mismatch");
  const Eigen::VectorXd difference = approx - reference;
  const double reference_norm2 = reference.dot(mass * reference);
  if (!(reference_norm2 > 0)) throw std::invalid_argument("relative_l2_error: reference has zero mass norm");
  return std::sqrt(std::max(0.0, difference.dot(mass * difference)) / reference_norm2);
}

double max_abs_error(const Eigen::VectorXd& approx, const Eigen::VectorXd& reference) {
  require_same_size(approx, reference, "max_abs_error");
  return (approx - reference).cwiseAbs().maxCoeff();
}

DistanceErrors distance_errors(const Eigen::VectorXd& approx, const Eigen::VectorXd& reference) {
  require_same_size(approx, reference, "distance_errors");
  const double largest = reference.maxCoeff();
  if (!(largest > 0)) throw std::invalid_argument("distance_errors: reference distances must have a positive maximum");
  const Eigen::ArrayXd error = (approx - reference).array().abs();
  return {error.mean() / largest, error.maxCoeff() / largest};
}

}  // namespace fem
