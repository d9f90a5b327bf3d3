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

// Distances on a mesh of several components are +∞ on the components no source lies in. Entries
// where approximation and reference are both +∞ agree and are left out of an error (replaced by 0
// in both, and not counted); one +∞ against a finite value makes the error +∞. Returns the number
// of entries left out (0: the vectors are returned unchanged).
Eigen::Index leave_out_unreached(Eigen::VectorXd& approx, Eigen::VectorXd& reference) {
  Eigen::Index left_out = 0;
  for (Eigen::Index i = 0; i < reference.size(); ++i)
    if (std::isinf(reference[i]) && std::isinf(approx[i]) && (reference[i] > 0) == (approx[i] > 0)) {
      reference[i] = approx[i] = 0;
      ++left_out;
    }
  return left_out;
}

}  // namespace

double relative_l2_error(const Eigen::VectorXd& approx, const Eigen::VectorXd& reference, const SparseMatrix& mass) {
  require_same_size(approx, reference, "relative_l2_error");
  if (mass.rows() != reference.size() || mass.cols() != reference.size())
    throw std::invalid_argument("relative_l2_error: mass matrix size mismatch");
  if (!approx.allFinite() || !reference.allFinite()) {
    Eigen::VectorXd a = approx, r = reference;
    if (leave_out_unreached(a, r) > 0) return relative_l2_error(a, r, mass);
  }
  const Eigen::VectorXd difference = approx - reference;
  const double reference_norm2 = reference.dot(mass * reference);
  if (!(reference_norm2 > 0)) throw std::invalid_argument("relative_l2_error: reference has zero mass norm");
  return std::sqrt(std::max(0.0, difference.dot(mass * difference)) / reference_norm2);
}

double max_abs_error(const Eigen::VectorXd& approx, const Eigen::VectorXd& reference) {
  require_same_size(approx, reference, "max_abs_error");
  if (!approx.allFinite() || !reference.allFinite()) {
    Eigen::VectorXd a = approx, r = reference;
    if (leave_out_unreached(a, r) > 0) return (a - r).cwiseAbs().maxCoeff();
  }
  return (approx - reference).cwiseAbs().maxCoeff();
}

DistanceErrors distance_errors(const Eigen::VectorXd& approx, const Eigen::VectorXd& reference) {
  require_same_size(approx, reference, "distance_errors");
  // Copies only where some entry is not finite (a mesh of several components).
  const bool finite = approx.allFinite() && reference.allFinite();
  Eigen::VectorXd a, r;
  Eigen::Index left_out = 0;
  if (!finite) {
    a = approx, r = reference;
    left_out = leave_out_unreached(a, r);
    if (left_out == a.size()) throw std::invalid_argument("distance_errors: no vertex is reached");
  }
  const Eigen::VectorXd& x = finite ? approx : a;
  const Eigen::VectorXd& y = finite ? reference : r;
  double largest = 0;  // the largest distance reached
  for (double value : y)
    if (std::isfinite(value)) largest = std::max(largest, value);
  if (!(largest > 0)) throw std::invalid_argument("distance_errors: reference distances must have a positive maximum");
  const Eigen::ArrayXd error = (x - y).array().abs();
  return {error.sum() / static_cast<double>(x.size() - left_out) / largest, error.maxCoeff() / largest};
}

}  // namespace fem
