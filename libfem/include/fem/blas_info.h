#pragma once
/// \file blas_info.h
/// Which BLAS/LAPACK the process actually runs on.
///
/// On Debian, CHOLMOD links `libblas.so.3` / `liblapack.so.3`, which are update-alternatives
/// symlinks: the file name says nothing about the implementation. These functions look up the
/// symbols in the running process and report the real shared object (symlinks resolved), so tools
/// and benchmarks can print it. The reference (netlib) BLAS makes CHOLMOD's supernodal
/// factorization many times slower than OpenBLAS; `scripts/setup.sh` switches it away.
#include <string>

namespace fem {

/// Absolute path (symlinks resolved) of the shared object that provides `dgemm_` in this process,
/// e.g. "/usr/lib/x86_64-linux-gnu/openblas-pthread/libblas.so.3". Empty when no BLAS is loaded
/// (for instance when nothing in the program links CHOLMOD and the linker dropped it).
std::string blas_library();

/// Same for LAPACK (`dpotrf_`). Empty when no LAPACK is loaded.
std::string lapack_library();

/// True when the loaded BLAS is OpenBLAS (it exports `openblas_get_config`, or its path names it).
bool blas_is_openblas();

}  // namespace fem
