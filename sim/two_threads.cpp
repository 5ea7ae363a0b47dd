// two_threads.cpp - the helper threads of two_threads.h
#include "sim/two_threads.h"

#include <array>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <system_error>
#include <utility>

namespace esim {
namespace {

// one kept thread: takes a task, runs it, says it is done, waits for the next
struct Helper {
  std::mutex m;
  std::condition_variable cv;  // a task given (the helper waits), or done (the caller waits)
  std::function<void()> task;
  bool given = false, done = false;

  void loop() {
    std::unique_lock<std::mutex> lock(m);
    for (;;) {
      cv.wait(lock, [this] { return given; });
      given = false;
      std::function<void()> t = std::move(task);
      task = nullptr;
      lock.unlock();
      t();
      t = nullptr;  // the task's captures released before it is reported done
      lock.lock();
      done = true;
      cv.notify_all();
    }
  }
};

// the helpers, started on first need and never stopped: the pool is never destroyed, so
// exit() does not wait for (or race with) a helper; the threads are detached and end with
// the process
class Pool {
 public:
  // an idle helper, marked busy (started if none is idle and fewer than kMaxHelpers are);
  // -1 if none
  int acquire() {
    std::lock_guard<std::mutex> lock(m_);
    for (int i = 0; i < count_; ++i)
      if (!busy_[i]) {
        busy_[i] = true;
        return i;
      }
    if (count_ == kMaxHelpers) return -1;
    auto h = std::make_unique<Helper>();
    try {
      std::thread(&Helper::loop, h.get()).detach();
    } catch (const std::system_error&) {
      return -1;
    }
    helpers_[count_] = std::move(h);
    busy_[count_] = true;
    return count_++;
  }
  void release(int i) {
    std::lock_guard<std::mutex> lock(m_);
    busy_[i] = false;
  }
  // helper i: its slot is written once, under m_, before i is handed out
  Helper& at(int i) { return *helpers_[i]; }
  int started() {
    std::lock_guard<std::mutex> lock(m_);
    return count_;
  }

 private:
  std::mutex m_;
  std::array<std::unique_ptr<Helper>, kMaxHelpers> helpers_;
  std::array<bool, kMaxHelpers> busy_{};
  int count_ = 0;
};

Pool& pool() {
  static Pool* p = new Pool;  // never destroyed (see Pool)
  return *p;
}

}  // namespace

HelperRun::HelperRun(HelperRun&& o) noexcept
    : helper_(std::exchange(o.helper_, -1)), own_(std::move(o.own_)) {}

HelperRun& HelperRun::operator=(HelperRun&& o) noexcept {
  if (this != &o) {
    wait();
    helper_ = std::exchange(o.helper_, -1);
    own_ = std::move(o.own_);
  }
  return *this;
}

void HelperRun::wait() {
  if (own_.joinable()) own_.join();
  if (helper_ < 0) return;
  Helper& h = pool().at(helper_);
  {
    std::unique_lock<std::mutex> lock(h.m);
    h.cv.wait(lock, [&h] { return h.done; });
    h.done = false;
  }
  pool().release(helper_);
  helper_ = -1;
}

HelperRun runOnHelper(std::function<void()> task) {
  HelperRun run;
  const int i = pool().acquire();
  if (i >= 0) {
    Helper& h = pool().at(i);
    {
      std::lock_guard<std::mutex> lock(h.m);
      h.task = std::move(task);
      h.given = true;
    }
    h.cv.notify_all();
    run.helper_ = i;
    return run;
  }
  try {
    run.own_ = std::thread(std::move(task));
  } catch (const std::system_error&) {
  }
  return run;
}

int helperThreadsStarted() { return pool().started(); }

}  // namespace esim
