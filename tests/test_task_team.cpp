// detail::TaskTeam (libice/src/task_team.h): the persistent team of the coarsener's parallel phase.
// Tasks record what they see in atomics and the checks run after run() returns: Catch2's
// assertions are not thread-safe.
#include <catch2/catch.hpp>

#include <atomic>
#include <chrono>
#include <numeric>
#include <stdexcept>
#include <thread>
#include <vector>

#include "task_team.h"

using ice::detail::TaskTeam;

namespace {

// Longer than the team's spin before a thread blocks (200 µs): after it the helpers are asleep.
void let_helpers_sleep() { std::this_thread::sleep_for(std::chrono::milliseconds(3)); }

// A round of two tasks that each wait for the other to start: it finishes only on two threads (or
// by the deadline, which the caller then reports). Returns whether both met; `helper_ran` is set
// when a task ran on a thread other than the caller's.
bool rendezvous(TaskTeam& team, bool& helper_ran, int helper_sleep_ms = 0) {
  std::atomic<int> started{0};
  std::atomic<bool> met{true}, other{false};
  const std::thread::id caller = std::this_thread::get_id();
  team.run(2, [&](int) {
    ++started;
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
    while (started.load() < 2 && std::chrono::steady_clock::now() < deadline) std::this_thread::yield();
    if (started.load() < 2) met = false;
    if (std::this_thread::get_id() != caller) {
      other = true;
      // The caller finishes first and must wait for this task: it spins, then blocks until woken.
      if (helper_sleep_ms > 0) std::this_thread::sleep_for(std::chrono::milliseconds(helper_sleep_ms));
    }
  });
  helper_ran = other.load();
  return met.load();
}

}  // namespace

TEST_CASE("TaskTeam runs every task of every round exactly once", "[task_team]") {
  for (int threads : {1, 2, 3, 8}) {
    TaskTeam team(threads);
    REQUIRE(team.threads() >= 1);
    REQUIRE(team.threads() <= threads);
    std::vector<std::atomic<int>> runs(64);
    for (auto& count : runs) count = 0;
    std::atomic<int> out_of_range{0};
    long long expected = 0;
    // Rounds back to back (helpers spinning) and after pauses longer than the spin (helpers asleep),
    // with fewer and more tasks than threads, and rounds of none.
    for (int round = 0; round < 400; ++round) {
      const int tasks = round % 17;  // 0..16
      expected += tasks;
      std::vector<std::atomic<int>> seen(static_cast<std::size_t>(tasks));
      for (auto& count : seen) count = 0;
      team.run(tasks, [&](int task) {
        if (task < 0 || task >= tasks) {
          ++out_of_range;
          return;
        }
        ++seen[static_cast<std::size_t>(task)];
        ++runs[static_cast<std::size_t>(task)];
      });
      int wrong = 0;  // every task of the round done once when run() returns
      for (const auto& count : seen) wrong += count.load() != 1;
      REQUIRE(wrong == 0);
      if (round % 50 == 0) let_helpers_sleep();
    }
    REQUIRE(out_of_range.load() == 0);
    long long total = 0;
    for (const auto& count : runs) total += count.load();
    REQUIRE(total == expected);
    let_helpers_sleep();  // the team is destroyed with its helpers asleep
  }
}

TEST_CASE("TaskTeam's helpers join rounds after sleeping, and the caller waits for their tasks", "[task_team]") {
  TaskTeam team(2);
  if (team.threads() < 2) {
    WARN("the system started no helper thread: nothing to check");
    return;
  }
  bool helper_ran = false;
  // Right after construction (the helper starting or spinning), then repeatedly with the helper
  // asleep (a lost wake-up would leave the caller alone: the rendezvous fails at its deadline).
  REQUIRE(rendezvous(team, helper_ran));
  REQUIRE(helper_ran);
  for (int round = 0; round < 5; ++round) {
    let_helpers_sleep();
    REQUIRE(rendezvous(team, helper_ran));
    REQUIRE(helper_ran);
  }
  // The helper's task outlasts the caller's spin: the caller blocks and the last task wakes it.
  for (int round = 0; round < 5; ++round) {
    REQUIRE(rendezvous(team, helper_ran, 5));
    REQUIRE(helper_ran);
  }
}

TEST_CASE("TaskTeam rethrows a task's exception, also from a helper, and stays usable", "[task_team]") {
  TaskTeam team(2);
  std::atomic<int> finished{0};
  REQUIRE_THROWS_WITH(team.run(8,
                               [&](int task) {
                                 if (task == 3) throw std::runtime_error("task 3 failed");
                                 ++finished;
                               }),
                      "task 3 failed");
  REQUIRE(finished.load() == 7);  // the other tasks still ran
  if (team.threads() == 2) {
    // Thrown on the helper's thread (whichever of the two met tasks is not the caller's).
    const std::thread::id caller = std::this_thread::get_id();
    std::atomic<int> started{0};
    REQUIRE_THROWS_WITH(team.run(2,
                                 [&](int) {
                                   ++started;
                                   const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
                                   while (started.load() < 2 && std::chrono::steady_clock::now() < deadline)
                                     std::this_thread::yield();
                                   if (std::this_thread::get_id() != caller) throw std::runtime_error("helper failed");
                                 }),
                        "helper failed");
  }
  std::atomic<int> after{0};
  team.run(5, [&](int) { ++after; });
  REQUIRE(after.load() == 5);
}
