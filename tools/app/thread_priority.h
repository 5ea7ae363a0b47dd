// thread_priority.h - `esim run --physics-first`: the drawing's threads in Linux's SCHED_IDLE
// class, so that they run only on CPU no other thread of the machine wants and the frame
// loop's physics is never descheduled for them (on 2 cores llvmpipe's two rasterizer threads
// and the drawing thread otherwise take the cores from it: README, the 1013-node target).
#pragma once

#include <string>

namespace esim::app {

// Puts every thread of this process whose name (/proc/self/task/TID/comm) begins with
// `prefix` (e.g. "llvmpipe-": Mesa's rasterizer threads), and the calling thread if
// andThisThread, in the SCHED_IDLE class. Returns how many threads it moved; 0 where Linux's
// per-thread scheduling is not to be had. A thread that ends meanwhile is skipped.
int idleThreadsNamed(const std::string& prefix, bool andThisThread);

}  // namespace esim::app
