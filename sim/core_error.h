// core_error.h - ESim's error type and always-on checks.
//
// ESIM_VERIFY(cond, msg) is always on and throws esim::Error with msg; it guards
// user input and invariants whose failure must give a message, never a crash.
// ESIM_ASSERT(cond) is for internal invariants and is compiled out in release.
// The command-line front end catches esim::Error, prints it and exits non-zero.
#pragma once

#include <cassert>
#include <stdexcept>
#include <string>

namespace esim {

// An error caused by input (scenario, mesh, option) or by a failed solve.
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace esim

#define ESIM_VERIFY(cond, msg)             \
  do {                                     \
    if (!(cond)) throw ::esim::Error(msg); \
  } while (0)

#ifdef NDEBUG
#define ESIM_ASSERT(cond) ((void)0)
#else
#define ESIM_ASSERT(cond) assert(cond)
#endif
