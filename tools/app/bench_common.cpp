// bench_common.cpp - what the `esim bench` commands share (bench_common.h).
#include "tools/app/bench_common.h"

#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <system_error>

#include "sim/core_error.h"
#include "sim/message_text.h"
#include "tools/app/run_output.h"
#include "tools/app/source_tree.h"

namespace esim::app {

std::vector<std::string> splitList(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ','))
    if (!item.empty()) out.push_back(item);
  return out;
}

std::vector<int> parseNodeCounts(const std::string& text, const std::string& command,
                                 const std::string& option) {
  std::vector<int> out;
  for (const std::string& item : splitList(text)) {
    char* end = nullptr;
    const long v = std::strtol(item.c_str(), &end, 10);
    ESIM_VERIFY(end != item.c_str() && *end == '\0' && v >= 27 && v <= 5000000,
                command + ": " + option + ": " + quoteInMessage(item) +
                    " is not a node count in [27, 5000000] (expected e.g. 1013,20000,50000)");
    out.push_back(static_cast<int>(v));
  }
  ESIM_VERIFY(!out.empty(), command + ": " + option + " is empty");
  return out;
}

namespace {

// a comma list, each item read by parse (false: not a valid item); errors name the option,
// the item and what is expected ("an integer in [1, 9]")
template <class T, class Parse>
std::vector<T> parseList(const std::string& text, const std::string& option,
                         const std::string& expected, const std::string& example,
                         const Parse& parse) {
  std::vector<T> out;
  for (const std::string& item : splitList(text)) {
    T v{};
    ESIM_VERIFY(parse(item, v), option + ": " + quoteInMessage(item) + " is not " + expected +
                                    " (expected e.g. " + example + ")");
    out.push_back(v);
  }
  ESIM_VERIFY(!out.empty(), option + " is empty (expected e.g. " + example + ")");
  return out;
}

}  // namespace

std::vector<int> parseIntegerList(const std::string& text, const std::string& option, long lo,
                                  long hi, const std::string& example) {
  const std::string expected =
      "an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
  return parseList<int>(text, option, expected, example, [&](const std::string& item, int& v) {
    char* end = nullptr;
    errno = 0;
    const long x = std::strtol(item.c_str(), &end, 10);
    v = static_cast<int>(x);
    return end != item.c_str() && *end == '\0' && errno == 0 && x >= lo && x <= hi;
  });
}

std::vector<double> parseNumberList(const std::string& text, const std::string& option, double lo,
                                    double hi, const std::string& example) {
  std::ostringstream expected;
  expected << "a number in [" << lo << ", " << hi << "]";
  return parseList<double>(
      text, option, expected.str(), example, [&](const std::string& item, double& v) {
        char* end = nullptr;
        v = std::strtod(item.c_str(), &end);
        return end != item.c_str() && *end == '\0' && std::isfinite(v) && v >= lo && v <= hi;
      });
}

namespace fs = std::filesystem;

std::string benchScenarioPath(const std::string& path, const std::string& defaultPath) {
  std::error_code ec;
  if (path != defaultPath || fs::is_regular_file(path, ec)) return path;
  const fs::path found = findSourceTreeFile(defaultPath);
  ESIM_VERIFY(!found.empty(), "--scenario: the default scene " + defaultPath +
                                  " is neither in the working folder nor in ESim's source tree; "
                                  "run from the source folder or give --scenario FILE");
  return found.string();
}

CsvOutput::CsvOutput(std::string path, const std::string& header) : path_(std::move(path)) {
  if (path_.empty()) return;
  std::error_code ec;
  ESIM_VERIFY(!fs::is_directory(path_, ec),
              "--csv: cannot write '" + path_ + "' (a folder; expected a file name)");
  const fs::path probe = path_ + ".probe" + std::to_string(::getpid());  // beside FILE
  const bool writable = std::ofstream(probe).good();
  fs::remove(probe, ec);
  ESIM_VERIFY(writable, "--csv: cannot write '" + path_ +
                            "' (does its folder exist, and may it be written?)");
  rows_ << header << '\n';
}

void CsvOutput::commit() {
  if (!path_.empty()) writeFileAtomic(path_, rows_.str());
}

}  // namespace esim::app
