// two_threads.h - work split in two shares, the second on a helper thread (the structural
// solve's triangular solves and per-tet stresses, a removal's pipelined update). The
// shares are fixed by the caller, never by timing, so results do not depend on the threads.
//
// Helper threads are kept for the process's life and reused: starting a thread cost
// 50-100 us here, and several a frame were started (strace -c on slab_cut: clone3 52 us and
// set_robust_list 72 us a call, strace's own overhead included; 585 starts in the
// run, 14 with the helpers). A task goes to an idle helper; up to kMaxHelpers are started, on first
// need; when all are busy (callers on several threads at once), a thread of its own is started for
// it, as before. A helper waits for work on a condition variable: no spinning between frames.
// Threads: any thread may call runOnHelper / runTwoShares; each HelperRun is waited for by
// the thread that made it. Not for use across fork() without exec (the helpers stay behind).
#pragma once

#include <functional>
#include <thread>

namespace esim {

// helper threads kept at most; more callers at once get threads of their own
constexpr int kMaxHelpers = 4;

class HelperRun {
 public:
  HelperRun() = default;
  HelperRun(const HelperRun&) = delete;
  HelperRun& operator=(const HelperRun&) = delete;
  HelperRun(HelperRun&& o) noexcept;
  HelperRun& operator=(HelperRun&& o) noexcept;
  ~HelperRun() { wait(); }
  bool running() const { return helper_ >= 0 || own_.joinable(); }  // a task not yet waited for
  void wait();  // blocks until the task is done; nothing if none

 private:
  friend HelperRun runOnHelper(std::function<void()> task);
  int helper_ = -1;  // the helper's index, or -1
  std::thread own_;  // or a thread of its own (all helpers busy)
};

// starts task on an idle helper (or a thread of its own); the returned run must be waited
// for (its destructor waits). task must not throw, and must leave the thread as it found it
// (its priority, its floating-point environment: the next task inherits them; the electric
// prefetch, which lowers its thread's priority, runs on a thread of its own). If no thread
// can be started, the run is not running and the task has not run (the caller runs it).
HelperRun runOnHelper(std::function<void()> task);

// the helpers started so far (tests)
int helperThreadsStarted();

// share(1) on a helper thread while share(0) runs here; with threads < 2 (or if no thread can
// be started) both here, 0 then 1. Returns whether a second thread ran. share must not throw.
template <typename F>
bool runTwoShares(int threads, const F& share) {
  HelperRun other;
  if (threads >= 2) other = runOnHelper([&share] { share(1); });
  share(0);
  if (!other.running()) {
    share(1);
    return false;
  }
  other.wait();
  return true;
}

}  // namespace esim
