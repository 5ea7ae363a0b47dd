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

nlohmann::json buildInfoJson(const BuildInfo& b) {
  return {{"esim", b.version},
          {"commit", b.commit},
          {"uncommitted_changes", b.dirty},
          {"compiler", b.compiler}};
}

std::optional<BuildInfo> buildInfoFromJson(const nlohmann::json& j) {
  if (!j.is_object()) return std::nullopt;
  const auto text = [&](const char* k) {
    return j.contains(k) && j[k].is_string() ? j[k].get<std::string>() : std::string("?");
  };
  return BuildInfo{text("esim"), text("commit"), text("uncommitted_changes"), text("compiler")};
}

}  // namespace esim::app
