// exit_codes.h - the process exit codes of `esim` (README), one per kind of outcome, and the
// code of an error of each kind (sim/core_error.h). Shared by the command and the run loop.
#pragma once

#include "sim/core_error.h"

namespace esim {

constexpr int kExitOk = 0;
constexpr int kExitFailure = 1;   // the run failed or was interrupted (outputs kept, partial)
constexpr int kExitBadInput = 2;  // bad scenario, mesh file or option
constexpr int kExitMismatch = 3;  // compare/hash-check found differences
constexpr int kExitInternal = 4;  // an internal check failed (a bug)

// the exit code of an error of this kind
inline int exitCodeOf(ErrorKind kind) {
  switch (kind) {
    case ErrorKind::Input:
      return kExitBadInput;
    case ErrorKind::Run:
      return kExitFailure;
    case ErrorKind::Internal:
      return kExitInternal;
  }
  return kExitInternal;
}

}  // namespace esim
