#pragma once
// Internal to libice: a small fork–join for the coarsener's regions and the triangulation's
// per-vertex passes.
#include <algorithm>
#include <atomic>
#include <exception>
#include <system_error>
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
  for (int t = 1; t < std::min(threads, tasks); ++t) {
    try {
      workers.emplace_back(work);
    } catch (const std::system_error&) {  // no more threads (a process limit): the others take the tasks
      break;
    }
  }
  work();
  for (std::thread& worker : workers) worker.join();
  for (const std::exception_ptr& error : errors)
    if (error) std::rethrow_exception(error);
}

// The threads of a pass over `size` elements: the hardware's (at most 8) from `parallel_from`
// elements on, else 1 (below that, starting threads costs more than it saves).
inline int threads_for(std::size_t size, std::size_t parallel_from) {
  if (size < parallel_from) return 1;
  return static_cast<int>(std::clamp(std::thread::hardware_concurrency(), 1u, 8u));
}

// Runs f(begin, end) over [0, count) cut into contiguous ranges (4 per thread, so a thread that
// finishes early takes another), on `threads` threads; one call f(0, count) when threads <= 1.
template <class Count, class F>
void run_ranges(int threads, Count count, F&& f) {
  if (threads <= 1 || count < 2) {
    f(Count{0}, count);
    return;
  }
  const int tasks = static_cast<int>(std::min<Count>(count, static_cast<Count>(4 * threads)));
  const auto bound = [&](int t) { return static_cast<Count>(static_cast<long long>(count) * t / tasks); };
  run_tasks(threads, tasks, [&](int t) { f(bound(t), bound(t + 1)); });
}

}  // namespace ice::detail
