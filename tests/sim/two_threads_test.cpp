// two_threads_test.cpp - the helper threads of sim/two_threads.h: a share runs on another
// thread, the same helper serves call after call, callers on several threads at once each
// get a thread, and a run is waited for before its results are read.
#include "sim/two_threads.h"

#include <gtest/gtest.h>

#include <atomic>
#include <numeric>
#include <set>
#include <thread>
#include <vector>

namespace esim {
namespace {

TEST(TwoThreads, TheSecondShareRunsOnAnotherThreadAndTheHelperIsKept) {
  std::thread::id ids[2];
  ASSERT_TRUE(runTwoShares(2, [&](int s) { ids[s] = std::this_thread::get_id(); }));
  EXPECT_EQ(ids[0], std::this_thread::get_id());
  EXPECT_NE(ids[1], std::this_thread::get_id());
  const int started = helperThreadsStarted();
  EXPECT_GE(started, 1);
  // the next calls from this thread go to the same kept helper: no thread started
  const std::thread::id helper = ids[1];
  for (int k = 0; k < 50; ++k) {
    ASSERT_TRUE(runTwoShares(2, [&](int s) { ids[s] = std::this_thread::get_id(); }));
    EXPECT_EQ(ids[1], helper) << k;
  }
  EXPECT_EQ(helperThreadsStarted(), started);
}

TEST(TwoThreads, OneThreadRunsBothSharesHereInOrder) {
  std::vector<int> order;
  std::thread::id ids[2];
  EXPECT_FALSE(runTwoShares(1, [&](int s) {
    order.push_back(s);
    ids[s] = std::this_thread::get_id();
  }));
  EXPECT_EQ(order, (std::vector<int>{0, 1}));
  EXPECT_EQ(ids[0], std::this_thread::get_id());
  EXPECT_EQ(ids[1], std::this_thread::get_id());
}

// the shares' results are complete when runTwoShares returns (a sum over halves, 200 times)
TEST(TwoThreads, ResultsAreCompleteWhenItReturns) {
  std::vector<double> v(100000);
  std::iota(v.begin(), v.end(), 1.0);
  for (int k = 0; k < 200; ++k) {
    double half[2] = {0, 0};
    runTwoShares(2, [&](int s) {
      const size_t n = v.size() / 2;
      for (size_t i = s * n; i < (s + 1) * n; ++i) half[s] += v[i];
    });
    ASSERT_EQ(half[0] + half[1], 100000.0 * 100001.0 / 2) << k;
  }
}

// callers on several threads at once, more than kMaxHelpers: every share runs once, the
// helpers kept never exceed kMaxHelpers (the others get threads of their own)
TEST(TwoThreads, ConcurrentCallersEachGetAThread) {
  constexpr int kCallers = kMaxHelpers + 3, kRounds = 40;
  std::atomic<int> ran{0};
  std::vector<std::thread> callers;
  for (int c = 0; c < kCallers; ++c)
    callers.emplace_back([&] {
      for (int r = 0; r < kRounds; ++r) {
        std::atomic<int> shares{0};
        runTwoShares(2, [&](int) {
          shares.fetch_add(1);
          std::this_thread::yield();
        });
        EXPECT_EQ(shares.load(), 2);
        ran.fetch_add(shares.load());
      }
    });
  for (auto& t : callers) t.join();
  EXPECT_EQ(ran.load(), 2 * kCallers * kRounds);
  EXPECT_LE(helperThreadsStarted(), kMaxHelpers);
}

// a task on a helper that itself starts one (the pipelined update's partner, from the
// update's own thread) does not wait on the pool
TEST(TwoThreads, AHelpersTaskMayUseAnotherHelper) {
  std::atomic<int> inner{0};
  HelperRun outer = runOnHelper([&] {
    HelperRun run = runOnHelper([&] { inner.store(7); });
    ASSERT_TRUE(run.running());
    run.wait();
  });
  ASSERT_TRUE(outer.running());
  outer.wait();
  EXPECT_FALSE(outer.running());
  EXPECT_EQ(inner.load(), 7);
}

// a run moved from is empty; a run destroyed unwaited is waited for by its destructor
TEST(TwoThreads, MovedAndDestroyedRunsAreWaitedFor) {
  std::atomic<int> done{0};
  {
    HelperRun a = runOnHelper([&] { done.fetch_add(1); });
    HelperRun b = std::move(a);
    EXPECT_FALSE(a.running());  // NOLINT(bugprone-use-after-move): the moved-from state
    EXPECT_TRUE(b.running());
  }
  EXPECT_EQ(done.load(), 1);
  HelperRun c = runOnHelper([&] { done.fetch_add(1); });
  c = runOnHelper([&] { done.fetch_add(1); });  // the first is waited for before it is replaced
  c.wait();
  EXPECT_EQ(done.load(), 3);
}

}  // namespace
}  // namespace esim
