// build_info.cpp - see build_info.h. The values come from build_info_values.h, which
// tools/app/build_info.cmake writes at every build.
#include "tools/app/build_info.h"

#include "build_info_values.h"

namespace esim::app {

const BuildInfo& buildInfo() {
  static const BuildInfo info {
    ESIM_BUILD_VERSION, ESIM_BUILD_COMMIT, ESIM_BUILD_DIRTY,
#if defined(__clang__)
        std::string("clang++ ") + __clang_version__
#elif defined(__GNUC__)
        std::string("g++ ") + __VERSION__
#else
        "unknown"
#endif
  };
  return info;
}

std::string buildInfoLine(const BuildInfo& b) {
  std::string line = "esim " + b.version + " (";
  if (b.commit == "unknown") {
    line += "commit unknown: no git checkout, or git could not read it";
  } else {
    line += "commit " + b.commit.substr(0, 12);
    if (b.dirty == "true") line += ", with uncommitted changes";
    if (b.dirty == "unknown") line += ", changes since it unknown";
  }
  return line + "; " + b.compiler + ")";
}

}  // namespace esim::app
