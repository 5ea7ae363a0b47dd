// core_error.h - ESim's errors, of three kinds, and its checks.
//
// Like MFEM's MFEM_VERIFY / MFEM_ASSERT pair, an error says what it is:
//   ErrorKind::Input     bad input (scenario, mesh, option, parameter): the front end exits 2
//                        and writes nothing;
//   ErrorKind::Run       a run that cannot go on (a solve that failed, all tissue removed,
//                        out of memory, an output that cannot be written): exit 1, the
//                        outputs so far are kept and marked partial;
//   ErrorKind::Internal  a broken internal invariant (a bug): exit 4, the message gives the
//                        condition, file and line.
// Checks:
//   ESIM_VERIFY(cond, msg)      always on; throws an Input error with msg (user input)
//   ESIM_RUN_CHECK(cond, msg)   always on; throws a Run error with msg (a solve, a resource)
//   ESIM_CHECK(cond)            always on; throws an Internal error "cond (file:line)"
//   ESIM_ASSERT(cond)           ESIM_CHECK in debug builds, nothing in release (hot loops)
// The core never exits or aborts: the front end (tools/app) maps the kind to the exit code.
#pragma once

#include <atomic>
#include <cstdio>
#include <stdexcept>
#include <string>

namespace esim {

enum class ErrorKind { Input, Run, Internal };

// an ESim error; thrown as is it is an Input error
class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& message, ErrorKind kind = ErrorKind::Input)
      : std::runtime_error(message), kind_(kind) {}
  ErrorKind kind() const { return kind_; }

 private:
  ErrorKind kind_;
};

// a run that cannot go on (exit 1, outputs so far kept)
class RunError : public Error {
 public:
  explicit RunError(const std::string& message) : Error(message, ErrorKind::Run) {}
};

// a broken internal invariant (exit 4): condition, file and line
class InternalError : public Error {
 public:
  InternalError(const char* condition, const char* file, int line)
      : Error(std::string("internal check failed: ") + condition + " (" + file + ":" +
                  std::to_string(line) + ")",
              ErrorKind::Internal) {}
};

// A stop asked from outside (SIGINT/SIGTERM in the front end): thrown by checkInterrupt()
// inside long work (explicit sub-steps, a rebuild, the recomputed lag frames, stages of a
// frame), so that a stop is honoured within one sub-step or one factorization instead of
// after a frame of minutes. The computation it leaves is incomplete: the caller stops.
class Interrupted : public Error {
 public:
  Interrupted() : Error("interrupted", ErrorKind::Run) {}
};

// The process-wide stop flag that checkInterrupt() reads (like MuJoCo's mjcb_* hooks, one
// per process: a signal is process-wide too); null (the default) never interrupts. The
// flag must outlive every computation that checks it.
inline std::atomic<const std::atomic<bool>*>& interruptFlag() {
  static std::atomic<const std::atomic<bool>*> flag{nullptr};
  return flag;
}
inline void setInterruptFlag(const std::atomic<bool>* flag) { interruptFlag() = flag; }

// throws Interrupted when the stop flag is set (one relaxed load: cheap in any loop)
inline void checkInterrupt() {
  const std::atomic<bool>* flag = interruptFlag().load(std::memory_order_relaxed);
  if (flag && flag->load(std::memory_order_relaxed)) throw Interrupted();
}

// a number as messages write it: %g ("29.97", "500", "1e-12"; std::to_string gives 0.000000)
inline std::string messageNumber(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%g", v);
  return b;
}

// "input", "run", "internal"
inline const char* errorKindName(ErrorKind kind) {
  switch (kind) {
    case ErrorKind::Input:
      return "input";
    case ErrorKind::Run:
      return "run";
    case ErrorKind::Internal:
      return "internal";
  }
  return "?";
}

}  // namespace esim

#define ESIM_VERIFY(cond, msg)             \
  do {                                     \
    if (!(cond)) throw ::esim::Error(msg); \
  } while (0)

#define ESIM_RUN_CHECK(cond, msg)             \
  do {                                        \
    if (!(cond)) throw ::esim::RunError(msg); \
  } while (0)

#define ESIM_CHECK(cond)                                                 \
  do {                                                                   \
    if (!(cond)) throw ::esim::InternalError(#cond, __FILE__, __LINE__); \
  } while (0)

#ifdef NDEBUG
#define ESIM_ASSERT(cond) ((void)0)
#else
#define ESIM_ASSERT(cond) ESIM_CHECK(cond)
#endif
