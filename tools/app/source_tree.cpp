// source_tree.cpp - files of the source tree (source_tree.h).
#include "tools/app/source_tree.h"

#include <system_error>

namespace esim::app {

namespace fs = std::filesystem;

fs::path findSourceTreeFile(const std::string& relative) {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec)
    for (fs::path dir = exe.parent_path(); !dir.empty(); dir = dir.parent_path()) {
      const fs::path p = dir / relative;
      if (fs::is_regular_file(p, ec)) return p;
      if (dir == dir.root_path()) break;
    }
#ifdef ESIM_SOURCE_DIR
  const fs::path p = fs::path(ESIM_SOURCE_DIR) / relative;
  if (fs::is_regular_file(p, ec)) return p;
#endif
  return {};
}

}  // namespace esim::app
