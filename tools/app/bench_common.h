// bench_common.h - option parsing shared by the `esim bench` commands.
#pragma once

#include <string>
#include <vector>

namespace esim::app {

// "a,b,c" -> {"a", "b", "c"} (empty items dropped)
std::vector<std::string> splitList(const std::string& text);

// "1013,20000" -> {1013, 20000}: node counts in [8, 5e6]; throws esim::Error naming
// `command`'s --sizes option and the bad item
std::vector<int> parseNodeCounts(const std::string& text, const std::string& command);

}  // namespace esim::app
