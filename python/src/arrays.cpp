#include "arrays.h"

#include <cmath>
#include <cstdint>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace ice_python {

namespace {

std::string shape_text(const py::array& array) {
  std::ostringstream text;
  text << '(';
  for (py::ssize_t d = 0; d < array.ndim(); ++d) text << (d ? ", " : "") << array.shape(d);
  if (array.ndim() == 1) text << ',';
  text << ')';
  return text.str();
}

std::string dtype_text(const py::array& array) { return py::str(array.dtype()).cast<std::string>(); }

// An n×3 array of exactly T in either memory order straight into an Eigen matrix (one copy, no
// conversion pass): the arrays ICE returns are column-major, numpy's own are row-major.
template <class T, class Matrix>
bool copy_n_by_3(const py::array& array, Matrix& out) {
  if (!py::isinstance<py::array_t<T>>(array)) return false;
  const py::ssize_t n = array.shape(0);
  const auto* data = static_cast<const T*>(array.data());
  if (array.flags() & py::array::f_style) {
    out = Eigen::Map<const Eigen::Matrix<T, Eigen::Dynamic, 3, Eigen::ColMajor>>(data, n, 3);
  } else if (array.flags() & py::array::c_style) {
    out = Eigen::Map<const Eigen::Matrix<T, Eigen::Dynamic, 3, Eigen::RowMajor>>(data, n, 3);
  } else {
    return false;
  }
  return true;
}

py::array as_array(const py::handle& object, const char* name) {
  if (object.is_none()) throw py::type_error(std::string(name) + " is None: an array is expected");
  py::array array = py::array::ensure(object);
  if (!array) throw py::type_error(std::string(name) + " is not array-like");
  return array;
}

bool is_real(const py::array& array) {
  const char kind = array.dtype().kind();
  return kind == 'f' || kind == 'i' || kind == 'u';
}
bool is_integer(const py::array& array) {
  const char kind = array.dtype().kind();
  return kind == 'i' || kind == 'u';
}

// A real array as C-contiguous float64 (a view when it already is one).
py::array_t<double, py::array::c_style> real_values(const py::array& array, const char* name, const char* expected) {
  if (!is_real(array))
    throw py::type_error(std::string(name) + " must be " + expected + " of real numbers, got dtype " + dtype_text(array));
  return py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(array);
}

// An integer array as C-contiguous int64 (a view when it already is one).
py::array_t<std::int64_t, py::array::c_style> integer_values(const py::array& array, const char* name,
                                                             const char* expected) {
  if (!is_integer(array))
    throw py::type_error(std::string(name) + " must be " + expected + " of integers, got dtype " + dtype_text(array));
  return py::array_t<std::int64_t, py::array::c_style | py::array::forcecast>::ensure(array);
}

[[noreturn]] void non_finite(const char* name, const std::string& where, double value) {
  std::ostringstream text;
  text << name << where << " is " << value << ": entries must be finite";
  throw py::value_error(text.str());
}

void require_n_by_3(const py::array& array, const char* name, const char* what) {
  if (array.ndim() != 2 || array.shape(1) != 3)
    throw py::value_error(std::string(name) + " must have shape (" + what + ", 3), got " + shape_text(array));
}

ice::Faces faces_checked(const py::handle& object, std::int64_t limit, const std::string& range_note, const char* name) {
  const py::array array = as_array(object, name);
  require_n_by_3(array, name, "m");
  if (!is_integer(array))
    throw py::type_error(std::string(name) + " must be an m×3 array of integers, got dtype " + dtype_text(array));
  if (array.shape(0) == 0) throw py::value_error(std::string(name) + " has no faces");
  const auto out_of_range = [&](Eigen::Index f, int k, std::int64_t v) {
    std::ostringstream text;
    text << name << '[' << f << ", " << k << "] = " << v << " is out of range" << range_note;
    throw py::value_error(text.str());
  };
  ice::Faces F;
  if (copy_n_by_3<int>(array, F)) {  // int32, either memory order: copied as it is, then checked
    for (Eigen::Index f = 0; f < F.rows(); ++f)
      for (int k = 0; k < 3; ++k)
        if (F(f, k) < 0 || F(f, k) >= limit) out_of_range(f, k, F(f, k));
    return F;
  }
  const auto values = integer_values(array, name, "an m×3 array");
  const py::ssize_t m = array.shape(0);
  F.resize(m, 3);
  const std::int64_t* data = values.data();
  for (py::ssize_t f = 0; f < m; ++f)
    for (int k = 0; k < 3; ++k) {
      const std::int64_t v = data[3 * f + k];
      if (v < 0 || v >= limit) out_of_range(f, k, v);
      F(f, k) = static_cast<int>(v);
    }
  return F;
}

}  // namespace

ice::Positions positions_argument(const py::handle& object, const char* name) {
  const py::array array = as_array(object, name);
  require_n_by_3(array, name, "n");
  ice::Positions V;
  if (!copy_n_by_3<double>(array, V)) {
    const auto values = real_values(array, name, "an n×3 array");
    V = Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>(values.data(), array.shape(0), 3);
  }
  for (Eigen::Index k = 0; k < 3; ++k)
    for (Eigen::Index v = 0; v < V.rows(); ++v)
      if (!std::isfinite(V(v, k))) non_finite(name, "[" + std::to_string(v) + ", " + std::to_string(k) + "]", V(v, k));
  return V;
}

ice::Faces faces_argument(const py::handle& object, Eigen::Index vertex_count, const char* name) {
  return faces_checked(object, vertex_count,
                       ": V has " + std::to_string(vertex_count) + " vertices (valid 0.." +
                           std::to_string(vertex_count - 1) + ")",
                       name);
}

ice::Faces faces_argument(const py::handle& object, const char* name) {
  return faces_checked(object, std::numeric_limits<int>::max(), " (vertex indices are 0 .. 2^31 - 2)", name);
}

ice::FaceLengths lengths_argument(const py::handle& object, Eigen::Index face_count, const char* name) {
  const py::array array = as_array(object, name);
  require_n_by_3(array, name, "m");
  if (array.shape(0) != face_count)
    throw py::value_error(std::string(name) + " has " + std::to_string(array.shape(0)) + " rows but F has " +
                          std::to_string(face_count) + " faces");
  const auto values = real_values(array, name, "an m×3 array");
  ice::FaceLengths L(face_count, 3);
  const double* data = values.data();
  for (Eigen::Index f = 0; f < face_count; ++f) {
    for (int k = 0; k < 3; ++k) {
      const double length = data[3 * f + k];
      if (!std::isfinite(length)) non_finite(name, "[" + std::to_string(f) + ", " + std::to_string(k) + "]", length);
      if (!(length > 0))
        throw py::value_error(std::string(name) + "[" + std::to_string(f) + ", " + std::to_string(k) + "] = " +
                              std::to_string(length) + ": edge lengths must be positive");
      L(f, k) = length;
    }
    for (int k = 0; k < 3; ++k)
      if (!(L(f, k) < L(f, (k + 1) % 3) + L(f, (k + 2) % 3))) {
        std::ostringstream text;
        text.precision(17);
        text << name << '[' << f << "] = (" << L(f, 0) << ", " << L(f, 1) << ", " << L(f, 2)
             << ") violates the strict triangle inequality (a degenerate or impossible triangle)";
        throw py::value_error(text.str());
      }
  }
  return L;
}

py::array_t<double, py::array::c_style> vector_values(const py::handle& object, Eigen::Index size, const char* name) {
  const py::array array = as_array(object, name);
  const bool column = array.ndim() == 2 && array.shape(1) == 1;
  if (!(array.ndim() == 1 || column) || array.shape(0) != size)
    throw py::value_error(std::string(name) + " must have " + std::to_string(size) + " entries (shape (" +
                          std::to_string(size) + ",)), got shape " + shape_text(array));
  auto values = real_values(array, name, "a vector");
  const double* data = values.data();
  for (Eigen::Index i = 0; i < size; ++i)
    if (!std::isfinite(data[i])) non_finite(name, "[" + std::to_string(i) + "]", data[i]);
  return values;
}

Eigen::VectorXd vector_argument(const py::handle& object, Eigen::Index size, const char* name) {
  return view(vector_values(object, size, name));
}

Eigen::MatrixXd matrix_argument(const py::handle& object, Eigen::Index rows, const char* name) {
  const py::array array = as_array(object, name);
  if (array.ndim() == 1) return vector_argument(array, rows, name);
  if (array.ndim() != 2 || array.shape(0) != rows || array.shape(1) < 1)
    throw py::value_error(std::string(name) + " must have shape (" + std::to_string(rows) + ",) or (" +
                          std::to_string(rows) + ", k), got " + shape_text(array));
  const auto values = real_values(array, name, "a matrix");
  const Eigen::Index cols = array.shape(1);
  Eigen::MatrixXd matrix(rows, cols);
  const double* data = values.data();
  for (Eigen::Index i = 0; i < rows; ++i)
    for (Eigen::Index j = 0; j < cols; ++j) {
      const double x = data[i * cols + j];
      if (!std::isfinite(x)) non_finite(name, "[" + std::to_string(i) + ", " + std::to_string(j) + "]", x);
      matrix(i, j) = x;
    }
  return matrix;
}

std::vector<ice::Index> index_argument(const py::handle& object, Eigen::Index size, const char* name) {
  py::array array = as_array(object, name);
  if (array.ndim() == 0) array = array.attr("reshape")(1);
  if (array.ndim() != 1) throw py::value_error(std::string(name) + " must be a list of indices, got shape " + shape_text(array));
  if (array.size() == 0) return {};
  const auto values = integer_values(array, name, "a list");
  std::vector<ice::Index> indices(static_cast<std::size_t>(array.size()));
  for (py::ssize_t i = 0; i < array.size(); ++i) {
    const std::int64_t v = values.data()[i];
    if (v < 0 || v >= size)
      throw py::value_error(std::string(name) + "[" + std::to_string(i) + "] = " + std::to_string(v) +
                            " is out of range (valid 0.." + std::to_string(size - 1) + ")");
    indices[static_cast<std::size_t>(i)] = static_cast<ice::Index>(v);
  }
  return indices;
}

Eigen::SparseMatrix<double> sparse_argument(const py::handle& object, const char* name, bool square) {
  if (object.is_none()) throw py::type_error(std::string(name) + " is None: a scipy.sparse matrix is expected");
  Eigen::SparseMatrix<double> result;
  if (py::hasattr(object, "tocsc")) {
    // CSC in canonical form (sorted, no duplicates: what Eigen's compressed storage is); a copy only
    // when the caller's matrix is not already that, which is then left as it was.
    py::object csc = object.attr("tocsc")();
    if (!csc.attr("has_canonical_format").cast<bool>()) {
      if (csc.is(object)) csc = csc.attr("copy")();
      csc.attr("sum_duplicates")();
    }
    const auto shape = csc.attr("shape").cast<std::pair<py::ssize_t, py::ssize_t>>();
    const py::array data_array = csc.attr("data");
    const auto data = real_values(data_array, name, "a matrix");
    const auto indices = py::array_t<int, py::array::c_style | py::array::forcecast>::ensure(csc.attr("indices"));
    const auto indptr = py::array_t<int, py::array::c_style | py::array::forcecast>::ensure(csc.attr("indptr"));
    const auto nonzeros = static_cast<Eigen::Index>(data.size());
    for (Eigen::Index k = 0; k < nonzeros; ++k)
      if (!std::isfinite(data.data()[k])) non_finite(name, " (stored entry " + std::to_string(k) + ")", data.data()[k]);
    result = Eigen::Map<const Eigen::SparseMatrix<double>>(shape.first, shape.second, nonzeros, indptr.data(),
                                                           indices.data(), data.data());
  } else {
    const py::array array = as_array(object, name);
    if (array.ndim() != 2) throw py::value_error(std::string(name) + " must be a matrix, got shape " + shape_text(array));
    const Eigen::MatrixXd dense = matrix_argument(array, array.shape(0), name);
    result = dense.sparseView();
  }
  if (square && result.rows() != result.cols())
    throw py::value_error(std::string(name) + " must be square, got " + std::to_string(result.rows()) + "×" +
                          std::to_string(result.cols()));
  return result;
}

namespace {
template <class Matrix>
py::object scipy_matrix(const Matrix& matrix, const py::handle& base, bool writeable) {
  const char* format = Matrix::IsRowMajor ? "csr_matrix" : "csc_matrix";
  const auto nonzeros = static_cast<py::ssize_t>(matrix.nonZeros());
  const auto outer = static_cast<py::ssize_t>(matrix.outerSize());
  py::array_t<double> data({nonzeros}, {static_cast<py::ssize_t>(sizeof(double))}, matrix.valuePtr(), base);
  py::array_t<int> indices({nonzeros}, {static_cast<py::ssize_t>(sizeof(int))}, matrix.innerIndexPtr(), base);
  py::array_t<int> indptr({outer + 1}, {static_cast<py::ssize_t>(sizeof(int))}, matrix.outerIndexPtr(), base);
  if (!writeable)
    for (py::array* array : {static_cast<py::array*>(&data), static_cast<py::array*>(&indices), static_cast<py::array*>(&indptr)})
      array->attr("setflags")(py::arg("write") = false);
  const py::object sparse = py::module_::import("scipy.sparse");
  return sparse.attr(format)(py::make_tuple(data, indices, indptr),
                             py::arg("shape") = py::make_tuple(matrix.rows(), matrix.cols()), py::arg("copy") = false);
}

template <class Matrix>
py::object owned_scipy(Matrix&& matrix) {
  matrix.makeCompressed();
  auto* owned = new Matrix(std::move(matrix));
  const py::capsule base(owned, [](void* p) { delete static_cast<Matrix*>(p); });
  return scipy_matrix(*owned, base, true);
}
}  // namespace

py::object scipy_view(const Eigen::SparseMatrix<double>& matrix, const py::handle& owner) {
  if (!matrix.isCompressed()) throw std::logic_error("scipy_view: the matrix is not compressed");
  return scipy_matrix(matrix, owner, false);
}
py::object scipy_view(const Eigen::SparseMatrix<double, Eigen::RowMajor, int>& matrix, const py::handle& owner) {
  if (!matrix.isCompressed()) throw std::logic_error("scipy_view: the matrix is not compressed");
  return scipy_matrix(matrix, owner, false);
}

py::object to_scipy(Eigen::SparseMatrix<double>&& matrix) { return owned_scipy(std::move(matrix)); }
py::object to_scipy(Eigen::SparseMatrix<double, Eigen::RowMajor, int>&& matrix) { return owned_scipy(std::move(matrix)); }

}  // namespace ice_python
