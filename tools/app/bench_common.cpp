// bench_common.cpp - what the `esim bench` commands share (bench_common.h).
#include "tools/app/bench_common.h"

#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <system_error>

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

namespace {

namespace fs = std::filesystem;

// FILE.tmp<pid>: beside FILE, so that the rename stays on one file system
fs::path temporaryBeside(const std::string& path) {
  return fs::path(path + ".tmp" + std::to_string(::getpid()));
}

}  // namespace

std::string benchScenarioPath(const std::string& path, const std::string& defaultPath) {
  std::error_code ec;
  if (path != defaultPath || fs::is_regular_file(path, ec)) return path;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec)
    for (fs::path dir = exe.parent_path(); !dir.empty(); dir = dir.parent_path()) {
      const fs::path p = dir / defaultPath;
      if (fs::is_regular_file(p, ec)) return p.string();
      if (dir == dir.root_path()) break;
    }
#ifdef ESIM_SOURCE_DIR
  const fs::path p = fs::path(ESIM_SOURCE_DIR) / defaultPath;
  if (fs::is_regular_file(p, ec)) return p.string();
#endif
  throw Error("--scenario: the default scene " + defaultPath +
              " is neither in the working folder nor in ESim's source tree; run from the "
              "source folder or give --scenario FILE");
}

CsvOutput::CsvOutput(std::string path, const std::string& header) : path_(std::move(path)) {
  if (path_.empty()) return;
  std::error_code ec;
  ESIM_VERIFY(!fs::is_directory(path_, ec),
              "--csv: cannot write '" + path_ + "' (a folder; expected a file name)");
  const fs::path probe = temporaryBeside(path_);
  const bool writable = std::ofstream(probe).good();
  fs::remove(probe, ec);
  ESIM_VERIFY(writable, "--csv: cannot write '" + path_ +
                            "' (does its folder exist, and may it be written?)");
  rows_ << header << '\n';
}

void CsvOutput::commit() {
  if (path_.empty()) return;
  const fs::path tmp = temporaryBeside(path_);
  std::error_code ec;
  {
    std::ofstream os(tmp, std::ios::binary);
    os << rows_.str();
    os.flush();
    if (!os.good()) {
      fs::remove(tmp, ec);
      throw Error("--csv: writing '" + path_ + "' failed (disk full?)", ErrorKind::Run);
    }
  }
  fs::rename(tmp, path_, ec);
  if (ec) {
    const std::string why = ec.message();
    fs::remove(tmp, ec);
    throw Error("--csv: cannot replace '" + path_ + "': " + why, ErrorKind::Run);
  }
}

}  // namespace esim::app
