#include "task_team.h"

#include "run_tasks.h"

#include <algorithm>
#include <chrono>
#include <system_error>

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#endif

namespace ice::detail {

namespace {

// A thread waits this long spinning before it blocks. A helper waiting for the next round: longer
// than the serial part between two rounds of the parallel phase (microseconds), shorter than a
// stage's serial Delaunay pass (milliseconds), which it would only burn a core through. run()'s
// caller waiting for the helpers' last tasks: blocking sooner hands the core to a preempted
// helper (or to other processes) instead of burning it.
constexpr auto kSpinTime = std::chrono::microseconds(200);

inline void pause() {
#if defined(__x86_64__) || defined(__i386__)
  _mm_pause();
#else
  std::this_thread::yield();
#endif
}

// Spins until done() or the time is up; returns done().
template <class Done>
bool spin_until(Done&& done, std::chrono::steady_clock::duration limit) {
  const auto start = std::chrono::steady_clock::now();
  for (int spins = 1;; ++spins) {
    if (done()) return true;
    pause();
    if (spins % 64 == 0 && std::chrono::steady_clock::now() - start > limit) return done();
  }
}

}  // namespace

TaskTeam::TaskTeam(int threads) {
  helpers_.reserve(static_cast<std::size_t>(std::max(threads - 1, 0)));  // no reallocation (a throw) once threads run
  for (int t = 1; t < threads; ++t) {
    try {
      helpers_.emplace_back([this] { helper_loop(); });
    } catch (const std::system_error&) {  // no more threads (a process limit): fewer helpers
      break;
    }
  }
}

TaskTeam::~TaskTeam() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_.store(true);
  }
  wake_.notify_all();
  for (std::thread& helper : helpers_) helper.join();
}

void TaskTeam::take_tasks() {
  for (int task; (task = next_.fetch_add(1, std::memory_order_relaxed)) < tasks_;) {
    try {
      call_(function_, task);
    } catch (...) {
      errors_[task] = std::current_exception();
    }
    // Publishes the task's writes to run()'s caller; the last task wakes it if it blocked (each
    // side writes, then reads the other's flag: one of them sees it).
    if (remaining_.fetch_sub(1) == 1 && caller_waiting_.load()) {
      { std::lock_guard<std::mutex> lock(mutex_); }
      done_.notify_one();
    }
  }
}

void TaskTeam::helper_loop() {
  // The generation the team was made with (not read here: the caller may have opened a round
  // before this thread started).
  std::uint64_t seen = kClosedAtStart;
  for (;;) {
    std::uint64_t open = 0;
    const auto round_open = [&] {
      open = generation_.load();
      return open != seen && open % 2 == 0;
    };
    if (!spin_until([&] { return stopping_.load() || round_open(); }, kSpinTime)) {
      std::unique_lock<std::mutex> lock(mutex_);
      sleepers_.fetch_add(1);
      wake_.wait(lock, [&] { return stopping_.load() || round_open(); });
      sleepers_.fetch_sub(1);
    }
    if (stopping_.load()) return;
    // Enter, then check that the round is still open: run() closes a round before it waits for the
    // helpers inside to leave (each side writes, then reads the other's flag: one of them sees it).
    entered_.fetch_add(1);
    if (generation_.load() == open) take_tasks();
    entered_.fetch_sub(1);
    seen = open;
  }
}

void TaskTeam::run_erased(int tasks, Call call, void* function) {
  if (helpers_.empty() || tasks <= 1) {  // on this thread alone, as detail::run_tasks does it
    run_tasks(1, tasks, [&](int task) { call(function, task); });
    return;
  }
  std::vector<std::exception_ptr> errors(static_cast<std::size_t>(tasks));
  // The round is closed and no helper is inside: the fields are ours to write.
  call_ = call;
  function_ = function;
  tasks_ = tasks;
  errors_ = errors.data();
  next_.store(0, std::memory_order_relaxed);
  remaining_.store(tasks, std::memory_order_relaxed);
  const std::uint64_t open = generation_.load() + 1;
  // From here to the close below nothing may throw (helpers would go on using `errors`): tasks'
  // exceptions are caught, and only a mutex could throw (std::system_error, a broken system).
  generation_.store(open);  // opens the round (and publishes the fields)
  if (sleepers_.load() > 0) {
    { std::lock_guard<std::mutex> lock(mutex_); }  // a helper between its check and its wait gets the notice
    wake_.notify_all();
  }
  take_tasks();
  // The helpers' last tasks: spin as long as a task takes, then block (a helper preempted inside
  // a task, e.g. by other processes' threads, needs a core more than this thread does).
  if (!spin_until([&] { return remaining_.load() == 0; }, kSpinTime)) {
    std::unique_lock<std::mutex> lock(mutex_);
    caller_waiting_.store(true);
    done_.wait(lock, [&] { return remaining_.load() == 0; });
    caller_waiting_.store(false);
  }
  generation_.store(open + 1);  // closed
  if (!spin_until([&] { return entered_.load() == 0; }, std::chrono::milliseconds(1)))
    while (entered_.load() > 0) std::this_thread::yield();
  for (const std::exception_ptr& error : errors)
    if (error) std::rethrow_exception(error);
}

}  // namespace ice::detail
