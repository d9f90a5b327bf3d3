#pragma once
// Internal to libice: a team of threads kept for many short fork–join rounds (the coarsener's
// parallel phase runs ~100 rounds of a few milliseconds each on a large mesh).
//
// Why not detail::run_tasks per round: it starts a thread per round, and a new (or woken) thread is
// placed on a core by the scheduler. Where the other cores run work of their own, even at the
// lowest priority (a batch's small meshes beside its largest one), a thread so placed often lands on
// the core of the thread that started it and waits there until the load balancer moves it.
// Measured (dragon_vrip_bin, 437k vertices, to 5 %, 2 threads, 16 regions, a busy loop at nice 19
// beside it): coarsen() 2.55 s alone, 2.85-2.92 s with the busy loop. The team's helpers start
// once and, between rounds, wait spinning on their own cores (then blocking, after a pause longer
// than a round's serial part), so a round starts without any thread placement.
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <exception>
#include <mutex>
#include <thread>
#include <type_traits>
#include <vector>

namespace ice::detail {

class TaskTeam {
 public:
  /// `threads` threads in all, the caller of run() included (helpers: threads − 1; fewer if the
  /// system refuses to start more).
  explicit TaskTeam(int threads);
  ~TaskTeam();
  TaskTeam(const TaskTeam&) = delete;
  TaskTeam& operator=(const TaskTeam&) = delete;

  /// The threads that run() uses, the caller included.
  int threads() const { return static_cast<int>(helpers_.size()) + 1; }

  /// Runs f(task) for task = 0..tasks−1 on the team (the calling thread included), each thread
  /// taking the next task when it finishes one, as detail::run_tasks does; returns when all are
  /// done and rethrows the first task's exception. Not reentrant: one run() at a time, from the
  /// thread that owns the team.
  template <class F>
  void run(int tasks, F&& f) {
    using Function = std::remove_reference_t<F>;
    run_erased(tasks, [](void* function, int task) { (*static_cast<Function*>(function))(task); },
               const_cast<void*>(static_cast<const void*>(&f)));
  }

 private:
  using Call = void (*)(void*, int);
  void run_erased(int tasks, Call call, void* function);
  void helper_loop();
  void take_tasks();  // runs tasks of the open round until none is left

  std::vector<std::thread> helpers_;
  // The round: written by run() while the round is closed (generation odd) and no helper that will
  // read them is inside (a helper entering late sees the round closed and reads nothing); read by
  // helpers only between entering an open round and leaving it.
  Call call_ = nullptr;
  void* function_ = nullptr;
  int tasks_ = 0;
  std::exception_ptr* errors_ = nullptr;
  std::atomic<int> next_{0};        // the next task to take
  std::atomic<int> remaining_{0};   // tasks not finished
  std::atomic<int> entered_{0};     // helpers inside the open round
  static constexpr std::uint64_t kClosedAtStart = 1;
  std::atomic<std::uint64_t> generation_{kClosedAtStart};  // even: a round is open; odd: closed
  std::atomic<bool> stopping_{false};  // set under mutex_
  std::atomic<int> sleepers_{0};       // helpers blocked on wake_
  std::atomic<bool> caller_waiting_{false};  // run()'s caller blocked on done_
  std::mutex mutex_;
  std::condition_variable wake_, done_;
};

}  // namespace ice::detail
