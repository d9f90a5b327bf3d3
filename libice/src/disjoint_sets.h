#pragma once
// Union-find for the validator (private to libice).
#include <algorithm>
#include <cstddef>
#include <numeric>
#include <vector>

namespace ice::detail {

/// Union-find with path halving; small and iterative so huge meshes cannot overflow the stack.
/// The representative of a set is its smallest element.
class DisjointSets {
 public:
  explicit DisjointSets(std::size_t n) { reset(n); }
  /// n singletons again (keeps the storage: the validator reuses one per vertex star).
  void reset(std::size_t n) {
    parent_.resize(n);
    std::iota(parent_.begin(), parent_.end(), 0);
  }
  std::size_t find(std::size_t x) {
    while (parent_[x] != x) {
      parent_[x] = parent_[parent_[x]];
      x = parent_[x];
    }
    return x;
  }
  void unite(std::size_t a, std::size_t b) {
    a = find(a);
    b = find(b);
    if (a != b) parent_[std::max(a, b)] = std::min(a, b);
  }

 private:
  std::vector<std::size_t> parent_;
};

}  // namespace ice::detail
