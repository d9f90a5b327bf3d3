// detail::TaskTeam (libice/src/task_team.h): the persistent team of the coarsener's parallel phase.
#include <catch2/catch.hpp>

#include <atomic>
#include <chrono>
#include <mutex>
#include <numeric>
#include <set>
#include <stdexcept>
#include <thread>
#include <vector>

#include "task_team.h"

using ice::detail::TaskTeam;

TEST_CASE("TaskTeam runs every task of every round exactly once", "[task_team]") {
  for (int threads : {1, 2, 3, 8}) {
    TaskTeam team(threads);
    REQUIRE(team.threads() >= 1);
    REQUIRE(team.threads() <= threads);
    std::vector<int> runs(64, 0);
    // Rounds back to back (helpers spinning) and after pauses longer than the spin (helpers asleep),
    // with fewer and more tasks than threads, and rounds of none.
    for (int round = 0; round < 400; ++round) {
      const int tasks = round % 17;  // 0..16
      std::vector<std::atomic<int>> seen(static_cast<std::size_t>(tasks));
      for (auto& count : seen) count = 0;
      team.run(tasks, [&](int task) {
        REQUIRE(task >= 0);
        REQUIRE(task < tasks);
        ++seen[static_cast<std::size_t>(task)];
        ++runs[static_cast<std::size_t>(task)];
      });
      for (const auto& count : seen) REQUIRE(count.load() == 1);  // done when run() returns
      if (round % 50 == 0) std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    int expected = 0;
    for (int round = 0; round < 400; ++round) expected += round % 17;
    REQUIRE(std::accumulate(runs.begin(), runs.end(), 0) == expected);
  }
}

TEST_CASE("TaskTeam spreads a round over its threads and rethrows a task's exception", "[task_team]") {
  TaskTeam team(2);
  if (team.threads() == 2) {
    // Two tasks that each wait for the other to start can only finish on two threads.
    std::atomic<int> started{0};
    std::set<std::thread::id> ids;
    std::mutex ids_mutex;
    team.run(2, [&](int) {
      ++started;
      const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
      while (started.load() < 2 && std::chrono::steady_clock::now() < deadline) std::this_thread::yield();
      std::lock_guard<std::mutex> lock(ids_mutex);
      ids.insert(std::this_thread::get_id());
    });
    REQUIRE(started.load() == 2);
    REQUIRE(ids.size() == 2);
  }
  std::atomic<int> finished{0};
  REQUIRE_THROWS_WITH(team.run(8,
                               [&](int task) {
                                 if (task == 3) throw std::runtime_error("task 3 failed");
                                 ++finished;
                               }),
                      "task 3 failed");
  REQUIRE(finished.load() == 7);  // the other tasks still ran
  // The team is usable after a failed round.
  std::atomic<int> after{0};
  team.run(5, [&](int) { ++after; });
  REQUIRE(after.load() == 5);
}
