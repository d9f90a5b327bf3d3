#include "fem/cholesky.h"

#include <cholmod.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <vector>

namespace fem {

using SuiteSparseLong = SuiteSparse_long;

/// CHOLMOD state. The cholmod_common is heap-allocated through Impl so the solver stays movable.
struct CholeskySolver::Impl {
  cholmod_common common{};
  cholmod_factor* factor = nullptr;
  bool factorized = false;
  // Lower-triangle pattern of the analysed matrix, to check that factorize() may reuse the analysis.
  std::vector<SuiteSparseLong> column_starts, row_indices;

  Impl() {
    cholmod_l_start(&common);
    common.supernodal = CHOLMOD_SUPERNODAL;  // dense supernodes go to BLAS/LAPACK
    common.print = 0;                        // failures are reported by exceptions instead
  }
  ~Impl() {
    if (factor) cholmod_l_free_factor(&factor, &common);
    cholmod_l_finish(&common);
  }
  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;

  /// Copies the lower triangle of A into a new CHOLMOD matrix (stype = -1); caller frees it.
  cholmod_sparse* lower_triangle(const Eigen::SparseMatrix<double>& A) {
    std::size_t nonzeros = 0;
    for (Eigen::Index j = 0; j < A.outerSize(); ++j)
      for (Eigen::SparseMatrix<double>::InnerIterator it(A, j); it; ++it)
        if (it.row() >= j) ++nonzeros;
    cholmod_sparse* lower = cholmod_l_allocate_sparse(static_cast<std::size_t>(A.rows()),
                                                      static_cast<std::size_t>(A.cols()), nonzeros,
                                                      /*sorted=*/1, /*packed=*/1, /*stype=*/-1, CHOLMOD_REAL,
                                                      &common);
    if (!lower) throw std::runtime_error("CHOLMOD: out of memory allocating the matrix");
    auto* starts = static_cast<SuiteSparseLong*>(lower->p);
    auto* rows = static_cast<SuiteSparseLong*>(lower->i);
    auto* values = static_cast<double*>(lower->x);
    SuiteSparseLong next = 0;
    for (Eigen::Index j = 0; j < A.outerSize(); ++j) {
      starts[j] = next;
      for (Eigen::SparseMatrix<double>::InnerIterator it(A, j); it; ++it)
        if (it.row() >= j) {
          rows[next] = it.row();
          values[next] = it.value();
          ++next;
        }
    }
    starts[A.outerSize()] = next;
    return lower;
  }

  bool same_pattern(const cholmod_sparse* lower) const {
    const auto* starts = static_cast<const SuiteSparseLong*>(lower->p);
    const auto* rows = static_cast<const SuiteSparseLong*>(lower->i);
    if (column_starts.size() != lower->ncol + 1) return false;
    if (!std::equal(column_starts.begin(), column_starts.end(), starts)) return false;
    return std::equal(row_indices.begin(), row_indices.end(), rows);
  }

  /// Pivot of column j (L_jj² for an LLᵀ factor, D_jj for LDLᵀ).
  std::vector<double> pivots() const {
    std::vector<double> result(factor->n);
    const auto* x = static_cast<const double*>(factor->x);
    if (factor->is_super) {
      const auto* super = static_cast<const SuiteSparseLong*>(factor->super);
      const auto* pi = static_cast<const SuiteSparseLong*>(factor->pi);
      const auto* px = static_cast<const SuiteSparseLong*>(factor->px);
      for (std::size_t s = 0; s < factor->nsuper; ++s) {
        // Supernode s stores columns super[s]..super[s+1]-1 as a dense column-major block with
        // pi[s+1]-pi[s] rows, its diagonal first.
        const SuiteSparseLong rows_in_block = pi[s + 1] - pi[s];
        for (SuiteSparseLong jj = 0; jj < super[s + 1] - super[s]; ++jj) {
          const double diagonal = x[px[s] + jj + jj * rows_in_block];
          result[static_cast<std::size_t>(super[s] + jj)] = diagonal * diagonal;
        }
      }
    } else {
      const auto* p = static_cast<const SuiteSparseLong*>(factor->p);
      for (std::size_t j = 0; j < factor->n; ++j) {
        const double diagonal = x[p[j]];  // the diagonal is stored first in each column
        result[j] = factor->is_ll ? diagonal * diagonal : diagonal;
      }
    }
    return result;
  }
};

CholeskySolver::CholeskySolver() : impl_(std::make_unique<Impl>()) {}
const char* to_string(CholeskyOrdering ordering) {
  switch (ordering) {
    case CholeskyOrdering::automatic: return "automatic";
    case CholeskyOrdering::amd: return "amd";
    case CholeskyOrdering::metis: return "metis";
    case CholeskyOrdering::nested_dissection: return "nested_dissection";
  }
  return "?";
}

CholeskySolver::CholeskySolver(const Eigen::SparseMatrix<double>& A) : CholeskySolver() { compute(A); }
CholeskySolver::~CholeskySolver() = default;
CholeskySolver::CholeskySolver(CholeskySolver&&) noexcept = default;
CholeskySolver& CholeskySolver::operator=(CholeskySolver&&) noexcept = default;

void CholeskySolver::analyze(const Eigen::SparseMatrix<double>& A) {
  if (A.rows() != A.cols()) throw std::invalid_argument("CholeskySolver: matrix must be square");
  if (!impl_) impl_ = std::make_unique<Impl>();  // revive a moved-from solver
  Impl& s = *impl_;
  if (s.factor) cholmod_l_free_factor(&s.factor, &s.common);
  s.factorized = false;
  cholmod_sparse* lower = s.lower_triangle(A);
  if (ordering_ == CholeskyOrdering::automatic) {
    s.common.nmethods = 0;  // CHOLMOD's default strategy
  } else {
    s.common.nmethods = 1;
    s.common.method[0].ordering = ordering_ == CholeskyOrdering::amd     ? CHOLMOD_AMD
                                  : ordering_ == CholeskyOrdering::metis ? CHOLMOD_METIS
                                                                         : CHOLMOD_NESDIS;
    s.common.postorder = 1;
  }
  s.factor = cholmod_l_analyze(lower, &s.common);
  const auto* starts = static_cast<const SuiteSparseLong*>(lower->p);
  const auto* rows = static_cast<const SuiteSparseLong*>(lower->i);
  s.column_starts.assign(starts, starts + lower->ncol + 1);
  s.row_indices.assign(rows, rows + starts[lower->ncol]);
  cholmod_l_free_sparse(&lower, &s.common);
  if (!s.factor) throw std::runtime_error("CHOLMOD: symbolic analysis failed");
}

void CholeskySolver::factorize(const Eigen::SparseMatrix<double>& A) {
  if (!impl_ || !impl_->factor) analyze(A);
  Impl& s = *impl_;
  if (A.rows() != A.cols() || static_cast<std::size_t>(A.rows()) != s.factor->n)
    throw std::invalid_argument("CholeskySolver::factorize: size differs from the analysed matrix");
  cholmod_sparse* lower = s.lower_triangle(A);
  if (!s.same_pattern(lower)) {
    cholmod_l_free_sparse(&lower, &s.common);
    throw std::invalid_argument("CholeskySolver::factorize: sparsity pattern differs from the analysed one");
  }
  s.factorized = false;
  cholmod_l_factorize(lower, s.factor, &s.common);
  // Diagonal of A, for the relative pivot test below.
  std::vector<double> diagonal(s.factor->n, 0.0);
  for (std::size_t j = 0; j < s.factor->n; ++j)
    if (s.column_starts[j] < s.column_starts[j + 1] &&
        s.row_indices[static_cast<std::size_t>(s.column_starts[j])] == static_cast<SuiteSparseLong>(j))
      diagonal[j] = static_cast<const double*>(lower->x)[s.column_starts[j]];
  cholmod_l_free_sparse(&lower, &s.common);

  // CHOLMOD eliminates the permuted matrix; report columns of the matrix the caller passed in.
  const auto* permutation = static_cast<const SuiteSparseLong*>(s.factor->Perm);
  auto original_column = [&](std::size_t k) {
    return static_cast<Eigen::Index>(permutation ? permutation[k] : static_cast<SuiteSparseLong>(k));
  };
  if (s.common.status == CHOLMOD_NOT_POSDEF || s.factor->minor < s.factor->n) {
    const Eigen::Index column = original_column(s.factor->minor);
    throw NotPositiveDefinite(column, "CHOLMOD: matrix not positive definite (elimination failed at column " +
                                          std::to_string(column) + ", step " +
                                          std::to_string(s.factor->minor) + " of the permuted matrix)");
  }
  if (s.common.status < CHOLMOD_OK) throw std::runtime_error("CHOLMOD: numeric factorisation failed");

  // A singular PSD matrix (e.g. a closed-surface Laplacian) often survives elimination with a
  // round-off-sized last pivot; catch it instead of returning a meaningless factor.
  const std::vector<double> pivot = s.pivots();
  for (std::size_t k = 0; k < pivot.size(); ++k) {
    const Eigen::Index column = original_column(k);
    const double a_jj = std::abs(diagonal[static_cast<std::size_t>(column)]);
    if (!(pivot[k] > pivot_tolerance_ * a_jj)) {
      char message[160];
      std::snprintf(message, sizeof message,
                    "matrix numerically singular: pivot %.3g at column %ld (diagonal %.3g, tolerance %.1e)",
                    pivot[k], static_cast<long>(column), a_jj, pivot_tolerance_);
      throw NotPositiveDefinite(column, message);
    }
  }
  s.factorized = true;
}

void CholeskySolver::compute(const Eigen::SparseMatrix<double>& A) {
  analyze(A);
  factorize(A);
}

Eigen::MatrixXd CholeskySolver::solve_multiple(const Eigen::MatrixXd& B) const {
  if (!is_factorized()) throw std::logic_error("CholeskySolver::solve: no successful factorisation");
  Impl& s = *impl_;
  if (static_cast<std::size_t>(B.rows()) != s.factor->n)
    throw std::invalid_argument("CholeskySolver::solve: right-hand side has the wrong number of rows");
  if (B.cols() == 0) return Eigen::MatrixXd(B.rows(), 0);
  // A dense header over B's column-major storage; CHOLMOD only reads it.
  cholmod_dense rhs{};
  rhs.nrow = static_cast<std::size_t>(B.rows());
  rhs.ncol = static_cast<std::size_t>(B.cols());
  rhs.nzmax = rhs.nrow * rhs.ncol;
  rhs.d = rhs.nrow;
  rhs.x = const_cast<double*>(B.data());
  rhs.z = nullptr;
  rhs.xtype = CHOLMOD_REAL;
  rhs.dtype = CHOLMOD_DOUBLE;
  cholmod_dense* solution = cholmod_l_solve(CHOLMOD_A, s.factor, &rhs, &s.common);
  if (!solution) throw std::runtime_error("CHOLMOD: solve failed");
  Eigen::MatrixXd X(B.rows(), B.cols());
  for (Eigen::Index c = 0; c < B.cols(); ++c)
    std::memcpy(X.col(c).data(), static_cast<const double*>(solution->x) + c * solution->d,
                sizeof(double) * static_cast<std::size_t>(B.rows()));
  cholmod_l_free_dense(&solution, &s.common);
  return X;
}

Eigen::VectorXd CholeskySolver::solve(const Eigen::VectorXd& b) const {
  return solve_multiple(Eigen::MatrixXd(b)).col(0);
}

bool CholeskySolver::is_factorized() const { return impl_ && impl_->factorized; }
bool CholeskySolver::is_supernodal() const { return impl_ && impl_->factor && impl_->factor->is_super; }
Eigen::Index CholeskySolver::rows() const {
  return impl_ && impl_->factor ? static_cast<Eigen::Index>(impl_->factor->n) : 0;
}

}  // namespace fem
