// The coarsener's removal queue (libice/src/removal_queue.h, private) against a brute-force
// reference: after any sequence of insertions, cost rises and falls, and removals, top() is the
// exact cheapest candidate by (cost, vertex), whichever tier it sits in.
#include <catch2/catch.hpp>

#include <cmath>
#include <random>
#include <set>
#include <utility>
#include <vector>

#include "removal_queue.h"

using namespace ice;
using detail::RemovalQueue;
using detail::VertexState;

namespace {

struct Reference {
  std::set<std::pair<double, Index>> entries;
  std::vector<double> cost;
  explicit Reference(Index n) : cost(static_cast<std::size_t>(n), -1) {}
  void set(Index v, double c) {
    erase(v);
    cost[v] = c;
    entries.insert({c, v});
  }
  void erase(Index v) {
    if (cost[v] >= 0) entries.erase({cost[v], v});
    cost[v] = -1;
  }
};

// Runs `steps` random operations on a queue of n vertices; costs come from `draw` (given the
// vertex's current cost, or −1 if it is not queued). Every pop is checked against the reference.
template <class Draw>
void check_against_reference(Index n, int steps, std::uint32_t seed, Draw&& draw) {
  LargeArray<VertexState> state(static_cast<std::size_t>(n));
  RemovalQueue queue(state);
  Reference reference(n);
  std::mt19937 rng(seed);
  std::uniform_int_distribution<Index> vertex(0, n - 1);
  std::uniform_real_distribution<double> unit(0, 1);
  int pops = 0;
  const auto pop_and_check = [&] {
    const RemovalQueue::Entry top = queue.top();
    const auto expected = *reference.entries.begin();
    REQUIRE(top.cost == expected.first);
    REQUIRE(top.vertex == expected.second);
    queue.erase(top.vertex);
    reference.erase(top.vertex);
    ++pops;
  };
  for (Index v = 0; v < n; ++v) {  // as the coarsener starts: every vertex a candidate
    const double c = draw(-1.0, rng);
    queue.set(v, c);
    reference.set(v, c);
  }
  for (int step = 0; step < steps; ++step) {
    const double op = unit(rng);
    if (op < 0.3) {  // a removal
      REQUIRE(queue.empty() == reference.entries.empty());
      if (!reference.entries.empty()) pop_and_check();
    } else if (op < 0.9) {  // a (re-)evaluation
      const Index v = vertex(rng);
      const double c = draw(reference.cost[v], rng);
      queue.set(v, c);
      reference.set(v, c);
    } else {  // no longer removable
      const Index v = vertex(rng);
      queue.erase(v);
      reference.erase(v);
    }
  }
  // Drain: every remaining candidate comes out in order, and nothing else does.
  while (!reference.entries.empty()) {
    REQUIRE_FALSE(queue.empty());
    pop_and_check();
  }
  CHECK(queue.empty());
  CHECK(pops > n / 2);
}

}  // namespace

TEST_CASE("the removal queue yields the exact cheapest candidate", "[coarsen][queue]") {
  SECTION("costs that mostly rise, as neighbours absorb mass (many move to the cold tier)") {
    check_against_reference(20000, 120000, 1, [](double old, std::mt19937& rng) {
      std::uniform_real_distribution<double> unit(0, 1);
      if (old < 0) return 1e-6 * (1 + 1000 * unit(rng));
      return unit(rng) < 0.8 ? old * (1 + 2 * unit(rng)) : old * unit(rng);
    });
  }
  SECTION("ties, zero costs and costs spanning many orders of magnitude") {
    check_against_reference(6000, 60000, 2, [](double, std::mt19937& rng) {
      std::uniform_int_distribution<int> pick(0, 9);
      const int k = pick(rng);
      if (k == 0) return 0.0;
      if (k < 4) return 0.25 * k;  // exact ties across vertices
      std::uniform_real_distribution<double> exponent(-300, 300);
      return std::pow(10.0, exponent(rng));
    });
  }
  SECTION("costs that only fall") {
    check_against_reference(5000, 40000, 3, [](double old, std::mt19937& rng) {
      std::uniform_real_distribution<double> unit(0, 1);
      return old < 0 ? 1 + unit(rng) : old * unit(rng);
    });
  }
}
