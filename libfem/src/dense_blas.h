#pragma once
// Internal to libfem (not installed): tall dense products by the Fortran BLAS that CHOLMOD already
// runs on (OpenBLAS on Debian, threaded and vectorised for the machine it runs on, which Eigen's own
// products, built for a portable baseline, are not).
#include <Eigen/Core>

#include <algorithm>
#include <limits>
#include <stdexcept>

extern "C" void dgemm_(const char* transa, const char* transb, const int* m, const int* n, const int* k, const double* alpha,
                       const double* a, const int* lda, const double* b, const int* ldb, const double* beta, double* c,
                       const int* ldc);
extern "C" void dsyrk_(const char* uplo, const char* trans, const int* n, const int* k, const double* alpha, const double* a,
                       const int* lda, const double* beta, double* c, const int* ldc);

namespace fem::detail {

inline int blas_size(Eigen::Index value) {
  if (value > std::numeric_limits<int>::max()) throw std::length_error("a dense block too large for BLAS (32-bit sizes)");
  return static_cast<int>(value);
}

/// C = alpha op(A) op(B) + beta C for column-major blocks (whole matrices, column or row ranges); op =
/// the transpose when asked. C must have the product's size (std::logic_error) and must not overlap
/// A or B (BLAS's rule).
inline void gemm(const Eigen::Ref<const Eigen::MatrixXd>& A, bool transpose_a, const Eigen::Ref<const Eigen::MatrixXd>& B,
                 bool transpose_b, Eigen::Ref<Eigen::MatrixXd> C, double alpha = 1.0, double beta = 0.0) {
  const Eigen::Index rows = transpose_a ? A.cols() : A.rows(), inner = transpose_a ? A.rows() : A.cols();
  const Eigen::Index cols = transpose_b ? B.rows() : B.cols();
  if ((transpose_b ? B.cols() : B.rows()) != inner || C.rows() != rows || C.cols() != cols)
    throw std::logic_error("gemm: sizes do not match");
  if (rows == 0 || cols == 0) return;
  if (inner == 0) {
    if (beta == 0)
      C.setZero();
    else
      C *= beta;
    return;
  }
  const int m = blas_size(rows), n = blas_size(cols), k = blas_size(inner);
  const int lda = blas_size(std::max<Eigen::Index>(1, A.outerStride())), ldb = blas_size(std::max<Eigen::Index>(1, B.outerStride()));
  const int ldc = blas_size(std::max<Eigen::Index>(1, C.outerStride()));
  dgemm_(transpose_a ? "T" : "N", transpose_b ? "T" : "N", &m, &n, &k, &alpha, A.data(), &lda, B.data(), &ldb, &beta,
         C.data(), &ldc);
}

/// The upper triangle of C = alpha Aᵀ A + beta C (C: A.cols() square, not overlapping A), column-major;
/// the strictly lower triangle is not written.
inline void syrk_upper(const Eigen::Ref<const Eigen::MatrixXd>& A, Eigen::Ref<Eigen::MatrixXd> C, double alpha = 1.0,
                       double beta = 0.0) {
  if (C.rows() != A.cols() || C.cols() != A.cols()) throw std::logic_error("syrk: sizes do not match");
  if (A.cols() == 0) return;
  if (A.rows() == 0) {
    if (beta == 0)
      C.triangularView<Eigen::Upper>().setZero();
    else
      C.triangularView<Eigen::Upper>() *= beta;
    return;
  }
  const int n = blas_size(A.cols()), k = blas_size(A.rows()), lda = blas_size(A.outerStride()), ldc = blas_size(C.outerStride());
  dsyrk_("U", "T", &n, &k, &alpha, A.data(), &lda, &beta, C.data(), &ldc);
}

/// Aᵀ B (C: A.cols() × B.cols(), resized) for tall A and B of one row count. With several threads and
/// OpenBLAS, the rows are cut into parts, each part's product one single-threaded BLAS call on the
/// threads, and the parts summed in order: OpenBLAS threads such a product by cutting the small
/// output, at about two thirds of its rate for the same flops cut by rows (docs/measurements.md,
/// "The refined eigenbasis"). The parts do not depend on the thread count, nor does the result;
/// OpenBLAS's thread count is restored after. Otherwise (one thread, fewer than 131,072 rows,
/// another BLAS) one BLAS call.
void gram_by_rows(const Eigen::Ref<const Eigen::MatrixXd>& A, const Eigen::Ref<const Eigen::MatrixXd>& B, Eigen::MatrixXd& C,
                  int threads);

/// Aᵀ diag(w) A (C: A.cols() square, both triangles; w = root_w², root_w >= 0), a band of rows scaled
/// by root_w at a time and its symmetric rank-k update added; the rows cut as by gram_by_rows.
void self_gram_by_rows(const Eigen::Ref<const Eigen::MatrixXd>& A, const Eigen::VectorXd& root_w, Eigen::MatrixXd& C,
                       int threads);

}  // namespace fem::detail
