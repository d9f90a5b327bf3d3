#pragma once
// Internal to libice: a small fork–join for the coarsener's regions and the triangulation's
// per-vertex passes.
#include <algorithm>
#include <atomic>
#include <exception>
#include <thread>
#include <vector>

namespace ice::detail {

// Runs f(task) for task = 0..tasks−1 on `threads` threads (the calling one included), each thread
// taking the next task when it finishes one (a task's result must not depend on which thread runs
// it); rethrows the first exception.
template <class F>
void run_tasks(int threads, int tasks, F&& f) {
  std::vector<std::exception_ptr> errors(static_cast<std::size_t>(tasks));
  std::atomic<int> next{0};
  const auto work = [&] {
    for (int task; (task = next.fetch_add(1)) < tasks;) {
      try {
        f(task);
      } catch (...) {
        errors[task] = std::current_exception();
      }
    }
  };
  std::vector<std::thread> workers;
  for (int t = 1; t < std::min(threads, tasks); ++t) workers.emplace_back(work);
  work();
  for (std::thread& worker : workers) worker.join();
  for (const std::exception_ptr& error : errors)
    if (error) std::rethrow_exception(error);
}

}  // namespace ice::detail
