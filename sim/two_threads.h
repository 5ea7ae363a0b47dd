// two_threads.h - work split in two shares, the second on a thread started for it (the
// structural solve's triangular solves and per-tet stresses). The shares are fixed by the
// caller, never by timing, so results do not depend on the threads.
#pragma once

#include <system_error>
#include <thread>

namespace esim {

// share(1) on a second thread while share(0) runs here; with threads < 2 (or if no thread can
// be started) both here, 0 then 1. Returns whether a second thread ran. share must not throw.
template <typename F>
bool runTwoShares(int threads, const F& share) {
  std::thread other;
  if (threads >= 2) try {
      other = std::thread([&share] { share(1); });
    } catch (const std::system_error&) {
    }
  share(0);
  if (!other.joinable()) {
    share(1);
    return false;
  }
  other.join();
  return true;
}

}  // namespace esim
