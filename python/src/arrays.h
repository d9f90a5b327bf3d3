#pragma once
/// \file arrays.h
/// numpy / scipy.sparse ↔ Eigen for the ice Python module: every array a caller passes is checked
/// here (shape, dtype, finiteness, index range) and refused with a ValueError or TypeError naming the
/// argument and the first offending entry, before any library code sees it. Results go back without
/// copies where the layouts allow (dense Eigen results are moved into numpy arrays, sparse ones are
/// viewed by scipy's index and value arrays).
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include "ice/mesh.h"

namespace ice_python {

namespace py = pybind11;

/// V: n×3 real array (any float or integer dtype), finite.
ice::Positions positions_argument(const py::handle& array, const char* name = "V");
/// F: m×3 integer array with entries in [0, vertex_count); m >= 1.
ice::Faces faces_argument(const py::handle& array, Eigen::Index vertex_count, const char* name = "F");
/// F without a known vertex count (intrinsic meshes): entries >= 0 and below 2^31 − 1.
ice::Faces faces_argument(const py::handle& array, const char* name = "F");
/// Per-face edge lengths, m×3, finite, positive, each face satisfying the triangle inequality.
ice::FaceLengths lengths_argument(const py::handle& array, Eigen::Index face_count, const char* name = "lengths");
/// A real vector of `size` finite entries (1-D, or n×1).
Eigen::VectorXd vector_argument(const py::handle& array, Eigen::Index size, const char* name);
/// The same without a copy where the layout allows: the caller's float64 contiguous array itself
/// (else a converted one), checked, kept alive by the returned object; view(array) maps it.
py::array_t<double, py::array::c_style> vector_values(const py::handle& array, Eigen::Index size, const char* name);
inline Eigen::Map<const Eigen::VectorXd> view(const py::array_t<double, py::array::c_style>& values) {
  return {values.data(), static_cast<Eigen::Index>(values.size())};
}
/// A real n×k matrix (k >= 1) of finite entries; a 1-D array is one column.
Eigen::MatrixXd matrix_argument(const py::handle& array, Eigen::Index rows, const char* name);
/// Integer indices (a sequence or a 1-D array), each in [0, size); duplicates kept.
std::vector<ice::Index> index_argument(const py::handle& indices, Eigen::Index size, const char* name);
/// A scipy.sparse matrix (any format) or a dense 2-D array as an Eigen column-major matrix; square
/// when `square`. Entries finite.
Eigen::SparseMatrix<double> sparse_argument(const py::handle& matrix, const char* name, bool square);

/// scipy.sparse.csc_matrix / csr_matrix viewing the matrix's own arrays (no copy): the matrix is
/// moved to the heap and owned by the arrays.
py::object to_scipy(Eigen::SparseMatrix<double>&& matrix);
py::object to_scipy(Eigen::SparseMatrix<double, Eigen::RowMajor, int>&& matrix);
/// The same viewing a compressed matrix that `owner` (a Python object) keeps alive, read-only: the
/// matrices a CoarseSpace or Proxy holds, which its solvers use (a change through the view would
/// make the two disagree).
py::object scipy_view(const Eigen::SparseMatrix<double>& matrix, const py::handle& owner);
py::object scipy_view(const Eigen::SparseMatrix<double, Eigen::RowMajor, int>& matrix, const py::handle& owner);
/// A numpy array owning `values` (no copy).
template <class T>
py::array_t<T> to_numpy(std::vector<T>&& values) {
  auto* owned = new std::vector<T>(std::move(values));
  py::capsule base(owned, [](void* p) { delete static_cast<std::vector<T>*>(p); });
  return py::array_t<T>({static_cast<py::ssize_t>(owned->size())}, {static_cast<py::ssize_t>(sizeof(T))}, owned->data(), base);
}

}  // namespace ice_python
