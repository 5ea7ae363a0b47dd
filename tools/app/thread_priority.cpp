// thread_priority.cpp - see thread_priority.h.
#include "tools/app/thread_priority.h"

#include <cstdlib>
#include <filesystem>
#include <fstream>

#ifdef __linux__
#include <sched.h>
#include <sys/syscall.h>
#include <unistd.h>
#endif

namespace esim::app {

int idleThreadsNamed(const std::string& prefix, bool andThisThread) {
#ifdef __linux__
  const auto idle = [](pid_t tid) {
    sched_param none{};
    none.sched_priority = 0;
    return sched_setscheduler(tid, SCHED_IDLE, &none) == 0;
  };
  int moved = andThisThread && idle(static_cast<pid_t>(syscall(SYS_gettid))) ? 1 : 0;
  std::error_code ec;
  for (const auto& task : std::filesystem::directory_iterator("/proc/self/task", ec)) {
    std::ifstream comm(task.path() / "comm");
    std::string name;
    if (!std::getline(comm, name) || name.compare(0, prefix.size(), prefix) != 0) continue;
    moved +=
        idle(static_cast<pid_t>(std::strtol(task.path().filename().c_str(), nullptr, 10))) ? 1 : 0;
  }
  return moved;
#else
  (void)prefix, (void)andThisThread;
  return 0;
#endif
}

}  // namespace esim::app
