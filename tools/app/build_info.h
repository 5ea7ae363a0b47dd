// build_info.h - which esim made a run: its version, the git commit of the source tree it was
// built from (and whether that tree's tracked files differed from the commit) and the
// compiler. Recorded in timing.json and hashes.json, compared by `esim compare`, printed by
// `esim --version`: a frame hash that changed is first a question of which code made it.
#pragma once

#include <nlohmann/json.hpp>
#include <optional>
#include <string>

namespace esim::app {

struct BuildInfo {
  std::string version;   // the project's (CMakeLists.txt), e.g. "0.1.0"
  std::string commit;    // 40 hex digits, or "unknown" (no git checkout, or git refused it)
  std::string dirty;     // "false", "true" (tracked files changed since the commit), "unknown"
  std::string compiler;  // e.g. "g++ 12.2.0"
};

// of this binary (the values are taken at each build, not at configure time)
const BuildInfo& buildInfo();

// one line: "esim 0.1.0 (commit 4f067ee1c2d3, with uncommitted changes; g++ 12.2.0)"
std::string buildInfoLine(const BuildInfo& b);

// as recorded in timing.json's "build", hashes.json's and a sweep result's "esim_build":
// {"esim", "commit", "uncommitted_changes", "compiler"}
nlohmann::json buildInfoJson(const BuildInfo& b);
// read back from such a record (a field that is not text reads "?"); none when j is not an
// object (a file from before esim recorded its build)
std::optional<BuildInfo> buildInfoFromJson(const nlohmann::json& j);

}  // namespace esim::app
