// Which BLAS the process runs on (fem/blas_info.h), and the tall Gram products cut by rows for it
// (dense_blas.h), which hold OpenBLAS to one thread in each caller.
#include "fem/blas_info.h"

#include "dense_blas.h"

#include <dlfcn.h>

#include <algorithm>
#include <cctype>
#include <climits>
#include <cstdlib>
#include <functional>
#include <mutex>
#include <vector>

namespace fem {
namespace {

// Path of the loaded object that defines `symbol`, symlinks resolved; empty if the symbol is absent.
std::string object_defining(const char* symbol) {
  void* address = dlsym(RTLD_DEFAULT, symbol);
  if (address == nullptr) return {};
  Dl_info info{};
  if (dladdr(address, &info) == 0 || info.dli_fname == nullptr || info.dli_fname[0] == '\0') return {};
  char resolved[PATH_MAX];
  if (realpath(info.dli_fname, resolved) != nullptr) return resolved;
  return info.dli_fname;
}

bool contains_ci(std::string haystack, const std::string& needle) {
  std::transform(haystack.begin(), haystack.end(), haystack.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return haystack.find(needle) != std::string::npos;
}

}  // namespace

std::string blas_library() { return object_defining("dgemm_"); }

std::string lapack_library() { return object_defining("dpotrf_"); }

bool blas_is_openblas() {
  const std::string blas = blas_library();
  if (blas.empty()) return false;
  if (contains_ci(blas, "openblas")) return true;
  // Ask the object that provides dgemm_ (and its dependencies) for OpenBLAS's own entry point; a
  // process-wide lookup could find an OpenBLAS pulled in by LAPACK next to a reference BLAS.
  void* handle = dlopen(blas.c_str(), RTLD_LAZY | RTLD_NOLOAD);
  if (handle == nullptr) return false;
  const bool has_config = dlsym(handle, "openblas_get_config") != nullptr;
  dlclose(handle);
  return has_config;
}

}  // namespace fem

namespace fem::detail {
namespace {

// While a scope is alive, BLAS calls made on several OpenMP threads each run on their caller alone.
// OpenBLAS built on its own threads (Debian's default) needs its thread count set to 1 for that,
// and the count is process-wide (`openblas_set_num_threads`): the first scope saves it and the last
// restores it (scopes may overlap when several threads of a program refine at once); a BLAS call
// made meanwhile by another part of the program runs on one thread: slower, not different. OpenBLAS
// built sequentially or on OpenMP (which runs a call made inside a parallel region on its caller)
// is left as it is. With another BLAS, `engaged()` is false and nothing is changed.
class SingleThreadedOpenBlas {
 public:
  SingleThreadedOpenBlas() {
    const Entries& e = entries();
    if (!e.openblas) return;
    engaged_ = true;
    if (e.set == nullptr || e.get == nullptr) return;  // not built on its own threads
    const std::lock_guard<std::mutex> lock(mutex_);
    if (depth_++ == 0) {
      saved_ = e.get();
      e.set(1);
    }
    holds_count_ = true;
  }
  ~SingleThreadedOpenBlas() {
    if (!holds_count_) return;
    const std::lock_guard<std::mutex> lock(mutex_);
    if (--depth_ == 0) entries().set(saved_);
  }
  SingleThreadedOpenBlas(const SingleThreadedOpenBlas&) = delete;
  SingleThreadedOpenBlas& operator=(const SingleThreadedOpenBlas&) = delete;
  bool engaged() const { return engaged_; }

 private:
  struct Entries {
    bool openblas = false;
    void (*set)(int) = nullptr;  // only when OpenBLAS runs on its own threads
    int (*get)() = nullptr;
  };
  // Looked up in the object that provides dgemm_ (as blas_is_openblas does): a process-wide lookup
  // could find an OpenBLAS loaded beside another BLAS.
  static const Entries& entries() {
    static const Entries found = [] {
      Entries e;
      const std::string blas = blas_library();
      if (blas.empty()) return e;
      void* handle = dlopen(blas.c_str(), RTLD_LAZY | RTLD_NOLOAD);
      if (handle == nullptr) return e;
      const auto parallel = reinterpret_cast<int (*)()>(dlsym(handle, "openblas_get_parallel"));
      e.set = reinterpret_cast<void (*)(int)>(dlsym(handle, "openblas_set_num_threads"));
      e.get = reinterpret_cast<int (*)()>(dlsym(handle, "openblas_get_num_threads"));
      e.openblas = parallel != nullptr || (e.set != nullptr && e.get != nullptr);
      // openblas_get_parallel: 0 sequential, 1 OpenBLAS's threads, 2 OpenMP (absent before 0.2.10).
      if (parallel != nullptr && parallel() != 1) {
        e.set = nullptr;
        e.get = nullptr;
      }
      dlclose(handle);  // the object stays loaded (RTLD_NOLOAD found it loaded by the program)
      return e;
    }();
    return found;
  }
  // The scopes alive and the thread count the first one saved (process-wide, as OpenBLAS's count is).
  static inline std::mutex mutex_;
  static inline int depth_ = 0;
  static inline int saved_ = 1;
  bool engaged_ = false;
  bool holds_count_ = false;
};

// Rows per part: at least 65,536 (a single-threaded product that long runs at the BLAS's full rate),
// at most 64 parts (their m × m partial sums stay small beside the n × m blocks).
Eigen::Index part_rows(Eigen::Index rows) { return std::max<Eigen::Index>(65536, (rows + 63) / 64); }

// Σ over parts of part(first, count, partial) (each writing its m × m partial from scratch), in
// part order; false when the products are not to be cut (one thread, short blocks, not OpenBLAS),
// C untouched.
bool sum_over_parts(Eigen::Index rows, int threads, Eigen::MatrixXd& C,
                    const std::function<void(Eigen::Index, Eigen::Index, Eigen::MatrixXd&)>& part) {
  const Eigen::Index size = part_rows(rows);
  if (threads < 2 || rows < 2 * size) return false;
  blas_size(rows);  // a block too large for BLAS throws here, not inside the parallel loop
  const SingleThreadedOpenBlas serial;
  if (!serial.engaged()) return false;
  const Eigen::Index parts = (rows + size - 1) / size;
  std::vector<Eigen::MatrixXd> partial(static_cast<std::size_t>(parts));
#pragma omp parallel for schedule(dynamic) num_threads(static_cast<int>(std::min<Eigen::Index>(threads, parts)))
  for (Eigen::Index p = 0; p < parts; ++p) {
    const Eigen::Index first = p * size;
    part(first, std::min(size, rows - first), partial[static_cast<std::size_t>(p)]);
  }
  C = partial[0];
  for (Eigen::Index p = 1; p < parts; ++p) C += partial[static_cast<std::size_t>(p)];
  return true;
}

}  // namespace

void gram_by_rows(const Eigen::Ref<const Eigen::MatrixXd>& A, const Eigen::Ref<const Eigen::MatrixXd>& B, Eigen::MatrixXd& C,
                  int threads) {
  if (A.rows() != B.rows()) throw std::logic_error("gram_by_rows: the blocks' row counts differ");
  const auto part = [&](Eigen::Index first, Eigen::Index count, Eigen::MatrixXd& out) {
    out.resize(A.cols(), B.cols());
    gemm(A.middleRows(first, count), true, B.middleRows(first, count), false, out);
  };
  if (sum_over_parts(A.rows(), threads, C, part)) return;
  C.resize(A.cols(), B.cols());
  gemm(A, true, B, false, C);
}

void self_gram_by_rows(const Eigen::Ref<const Eigen::MatrixXd>& A, const Eigen::VectorXd& root_w, Eigen::MatrixXd& C,
                       int threads) {
  if (root_w.size() != A.rows()) throw std::logic_error("self_gram_by_rows: one weight per row");
  const Eigen::Index m = A.cols();
  // Bands of the scaled rows: no n-row copy of diag(root_w) A is kept.
  constexpr Eigen::Index kBand = 16384;  // 4,096 rows was slower with OpenBLAS (docs/measurements.md, "The refined eigenbasis")
  const auto rows_into = [&](Eigen::Index first, Eigen::Index count, Eigen::MatrixXd& out) {
    out = Eigen::MatrixXd::Zero(m, m);
    Eigen::MatrixXd band;
    for (Eigen::Index b = first; b < first + count; b += kBand) {
      const Eigen::Index rows = std::min(kBand, first + count - b);
      band.noalias() = root_w.segment(b, rows).asDiagonal() * A.middleRows(b, rows);
      syrk_upper(band, out, 1.0, 1.0);
    }
  };
  if (m == 0) {
    C.resize(0, 0);
    return;
  }
  if (!sum_over_parts(A.rows(), threads, C, rows_into)) rows_into(0, A.rows(), C);
  C.triangularView<Eigen::StrictlyLower>() = C.transpose();
}

}  // namespace fem::detail
