// Tests for tools/app/thread_priority.cpp: the caller and the threads named with the prefix
// go to SCHED_IDLE, another thread stays where it was.
#include "tools/app/thread_priority.h"

#include <gtest/gtest.h>
#include <pthread.h>
#include <sched.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <atomic>
#include <condition_variable>
#include <mutex>
#include <thread>

namespace esim::app {
namespace {

// a thread that names itself, tells its id and waits until released
struct NamedThread {
  std::atomic<pid_t> tid{0};
  std::mutex m;
  std::condition_variable cv;
  bool release = false;
  std::thread t;
  explicit NamedThread(const char* name) {
    t = std::thread([this, name] {
      pthread_setname_np(pthread_self(), name);
      tid = static_cast<pid_t>(syscall(SYS_gettid));
      std::unique_lock lock(m);
      cv.wait(lock, [this] { return release; });
    });
    while (tid == 0) std::this_thread::yield();
  }
  ~NamedThread() {
    {
      std::lock_guard lock(m);
      release = true;
    }
    cv.notify_all();
    t.join();
  }
};

TEST(ThreadPriority, TheCallerAndTheThreadsWithThePrefixGoIdleOthersStay) {
  NamedThread raster0("llvmpipe-0"), raster1("llvmpipe-1"), other("esim-other");
  int moved = 0, callerPolicy = -1;
  std::thread drawing([&] {  // the caller: esim run's drawing thread
    moved = idleThreadsNamed("llvmpipe-", true);
    callerPolicy = sched_getscheduler(0);
  });
  drawing.join();
  EXPECT_EQ(moved, 3);
  EXPECT_EQ(callerPolicy, SCHED_IDLE);
  EXPECT_EQ(sched_getscheduler(raster0.tid), SCHED_IDLE);
  EXPECT_EQ(sched_getscheduler(raster1.tid), SCHED_IDLE);
  EXPECT_EQ(sched_getscheduler(other.tid), SCHED_OTHER);
  EXPECT_EQ(sched_getscheduler(0), SCHED_OTHER);  // this thread (the frame loop's) stays
}

// drawn in the loop (--no-draw-thread): only the named threads go, never the caller
TEST(ThreadPriority, WithoutTheCallerOnlyTheNamedThreadsGo) {
  NamedThread raster("llvmpipe-0");
  int moved = 0, callerPolicy = -1;
  std::thread loop([&] {
    moved = idleThreadsNamed("llvmpipe-", false);
    callerPolicy = sched_getscheduler(0);
  });
  loop.join();
  EXPECT_EQ(moved, 1);
  EXPECT_EQ(callerPolicy, SCHED_OTHER);
  EXPECT_EQ(sched_getscheduler(raster.tid), SCHED_IDLE);
}

}  // namespace
}  // namespace esim::app
