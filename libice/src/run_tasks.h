#pragma once
// Internal to libice: a small fork–join for the coarsener's regions and the triangulation's
// per-vertex passes.
#ifdef __linux__
#include <sched.h>
#endif

#include <algorithm>
#include <atomic>
#include <cstdlib>
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
// The threads a "0: all cores" option runs on: the hardware threads this process may run on (its CPU
// affinity where the system says: taskset, a batch scheduler's or a container's cpuset; else
// std::thread's count), at most OMP_NUM_THREADS when that is set — the one knob that also bounds
// libfem's OpenMP loops and the BLAS, so a caller that runs several processes side by side sets one
// variable; at least 1.
inline int available_threads() {
  int count = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
#ifdef __linux__
  cpu_set_t set;
  if (sched_getaffinity(0, sizeof(set), &set) == 0) count = std::max(1, CPU_COUNT(&set));
#endif
  if (const char* omp = std::getenv("OMP_NUM_THREADS")) {
    char* end = nullptr;
    const long limit = std::strtol(omp, &end, 10);  // OpenMP's list form "4,2": its first level
    if (end != omp && limit > 0) count = static_cast<int>(std::min<long>(count, limit));
  }
  return count;
}

inline int threads_for(std::size_t size, std::size_t parallel_from) {
  if (size < parallel_from) return 1;
  return std::clamp(available_threads(), 1, 8);
}

// The threads an option asks for: `requested`, or one per available hardware thread for 0; at most 64.
inline int requested_threads(int requested) {
  return std::min(requested > 0 ? requested : available_threads(), 64);
}

// How many contiguous ranges run_ranges cuts [0, count) into on `threads` threads: 4 per thread (so
// a thread that finishes early takes another), one when threads <= 1.
template <class Count>
int range_count(int threads, Count count) {
  return threads <= 1 || count < 2 ? 1 : static_cast<int>(std::min<Count>(count, static_cast<Count>(4 * threads)));
}

// Runs f(range, begin, end) over those ranges of [0, count) on `threads` threads (range numbers
// 0 .. range_count − 1, in the order of the ranges): per-range results can be kept in order.
template <class Count, class F>
void run_numbered_ranges(int threads, Count count, F&& f) {
  const int ranges = range_count(threads, count);
  if (ranges == 1) {
    f(0, Count{0}, count);
    return;
  }
  const auto bound = [&](int t) { return static_cast<Count>(static_cast<long long>(count) * t / ranges); };
  run_tasks(threads, ranges, [&](int t) { f(t, bound(t), bound(t + 1)); });
}

// Runs f(begin, end) over the same ranges.
template <class Count, class F>
void run_ranges(int threads, Count count, F&& f) {
  run_numbered_ranges(threads, count, [&](int, Count begin, Count end) { f(begin, end); });
}

}  // namespace ice::detail
