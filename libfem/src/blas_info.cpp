#include "fem/blas_info.h"

#include <dlfcn.h>

#include <algorithm>
#include <cctype>
#include <climits>
#include <cstdlib>

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
