// bench_common.cpp - option parsing shared by the `esim bench` commands (bench_common.h).
#include "tools/app/bench_common.h"

#include <cstdlib>
#include <sstream>

#include "sim/core_error.h"

namespace esim::app {

std::vector<std::string> splitList(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ','))
    if (!item.empty()) out.push_back(item);
  return out;
}

std::vector<int> parseNodeCounts(const std::string& text, const std::string& command) {
  std::vector<int> out;
  for (const std::string& item : splitList(text)) {
    char* end = nullptr;
    const long v = std::strtol(item.c_str(), &end, 10);
    ESIM_VERIFY(end != item.c_str() && *end == '\0' && v >= 8 && v <= 5000000,
                command + ": --sizes: '" + item +
                    "' is not a node count in [8, 5000000] (expected e.g. 1013,20000,50000)");
    out.push_back(static_cast<int>(v));
  }
  ESIM_VERIFY(!out.empty(), command + ": --sizes is empty");
  return out;
}

}  // namespace esim::app
