// run_output.cpp - the output folder of a run (see run_output.h).
#include "tools/app/run_output.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>

#include "sim/core_error.h"

namespace esim::app {

namespace fs = std::filesystem;

namespace {

constexpr const char* kMarker = ".esim-run";

bool isEmptyFolder(const fs::path& dir) {
  std::error_code ec;
  return fs::is_directory(dir, ec) && fs::directory_iterator(dir, ec) == fs::directory_iterator();
}

// the nearest existing ancestor of p (p itself when it exists)
fs::path existingAncestor(fs::path p) {
  std::error_code ec;
  p = fs::absolute(p, ec);
  while (!p.empty() && !fs::exists(p, ec)) {
    const fs::path parent = p.parent_path();
    if (parent == p) break;
    p = parent;
  }
  return p;
}

}  // namespace

bool isEsimRunFolder(const fs::path& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return false;
  if (fs::exists(dir / kMarker, ec)) return true;
  return fs::exists(dir / "timing.json", ec) && fs::exists(dir / "scenario.yaml", ec) &&
         fs::exists(dir / "summary.txt", ec);
}

// true when another process holds the flock of the folder (an esim run writing it)
bool lockedByAnother(const fs::path& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return false;
  const bool locked = ::flock(fd, LOCK_EX | LOCK_NB) != 0 && errno == EWOULDBLOCK;
  ::close(fd);  // releases the probe's own lock, if it got one
  return locked;
}

std::string anotherRunMessage(const fs::path& dir) {
  return "-o " + dir.string() +
         ": another esim run is writing this folder (its .partial is locked); wait for it to "
         "end or give another folder (nothing was changed)";
}

RunOutput::RunOutput(fs::path dir, bool overwrite) : dir_(std::move(dir)), overwrite_(overwrite) {
  ESIM_VERIFY(!dir_.empty(), "-o: the output folder is empty");
  // "out/x/" -> "out/x", "." -> the working folder: the partial folder is a sibling
  fs::path norm = fs::absolute(dir_).lexically_normal();
  if (!norm.has_filename()) norm = norm.parent_path();
  ESIM_VERIFY(norm != norm.root_path(),
              "-o " + dir_.string() + ": not a folder a run can own (the root)");
  partial_ = fs::path(norm.string() + ".partial");
  dir_ = norm;
  std::error_code ec;
  ESIM_VERIFY(!lockedByAnother(partial_), anotherRunMessage(dir_));
  checkFinal();
  if (fs::exists(partial_, ec))
    ESIM_VERIFY(isEsimRunFolder(partial_) || isEmptyFolder(partial_),
                partial_.string() +
                    ": exists and is not an ESim run's partial output; move it "
                    "away or give another -o folder (nothing was changed)");
  const fs::path anchor = existingAncestor(dir_.parent_path());
  ESIM_VERIFY(fs::is_directory(anchor, ec),
              "-o " + dir_.string() + ": " + anchor.string() + " is not a folder");
  ESIM_VERIFY(::access(anchor.c_str(), W_OK | X_OK) == 0,
              "-o " + dir_.string() + ": cannot write in " + anchor.string() +
                  " (permission denied); give a writable folder");
}

void RunOutput::checkFinal() const {
  std::error_code ec;
  if (fs::exists(dir_, ec)) {
    ESIM_VERIFY(fs::is_directory(dir_, ec),
                "-o " + dir_.string() +
                    ": a file is there; give another folder (a run never "
                    "replaces a file)");
    if (!isEmptyFolder(dir_)) {
      ESIM_VERIFY(isEsimRunFolder(dir_),
                  "-o " + dir_.string() +
                      ": the folder exists and holds files that are not an "
                      "ESim run; give a new or empty folder (nothing was changed)");
      ESIM_VERIFY(overwrite_, "-o " + dir_.string() +
                                  ": holds an earlier ESim run; add --overwrite to replace it, "
                                  "or give another folder (nothing was changed)");
    }
  }
}

void RunOutput::create() {
  ESIM_CHECK(lockFd_ < 0);
  fs::create_directories(partial_.parent_path());
  bool made = false;  // DIR.partial/ created here (removed again if refused)
  for (int attempt = 0; lockFd_ < 0; ++attempt) {
    if (::mkdir(partial_.c_str(), 0777) == 0)
      made = true;
    else
      ESIM_VERIFY(errno == EEXIST, "-o " + dir_.string() + ": cannot create " + partial_.string() +
                                       ": " + std::strerror(errno));
    const int fd = ::open(partial_.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (fd < 0 && errno == ENOENT && attempt < 100) continue;  // renamed away meanwhile
    ESIM_VERIFY(fd >= 0, "-o " + dir_.string() + ": cannot open " + partial_.string() + ": " +
                             std::strerror(errno));
    if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
      ::close(fd);
      throw Error(anotherRunMessage(dir_));
    }
    // still DIR.partial (a run completing renames its own to DIR): else try again
    struct stat locked {
    }, named{};
    if (::fstat(fd, &locked) == 0 && ::stat(partial_.c_str(), &named) == 0 &&
        locked.st_dev == named.st_dev && locked.st_ino == named.st_ino) {
      lockFd_ = fd;
    } else {
      ::close(fd);
      ESIM_VERIFY(attempt < 100, "-o " + dir_.string() + ": " + partial_.string() +
                                     " keeps changing; is another run using it?");
    }
  }
  try {
    checkFinal();  // again, under the lock: a run may have completed there since
    ESIM_VERIFY(isEsimRunFolder(partial_) || isEmptyFolder(partial_),
                partial_.string() +
                    ": exists and is not an ESim run's partial output; move it "
                    "away or give another -o folder (nothing was changed)");
  } catch (...) {
    if (made) {
      std::error_code ec;
      fs::remove(partial_, ec);  // empty, ours
    }
    ::close(lockFd_);
    lockFd_ = -1;
    throw;
  }
  // an earlier run's partial output goes; the folder itself stays (it carries the lock)
  for (const fs::directory_entry& e : fs::directory_iterator(partial_)) fs::remove_all(e.path());
  std::ofstream(partial_ / kMarker) << "esim run output (partial until renamed)\n";
}

RunOutput::~RunOutput() {
  if (lockFd_ >= 0) ::close(lockFd_);
}

void RunOutput::commit() {
  std::error_code ec;
  if (fs::exists(dir_, ec)) {
    // checked in the constructor: empty, or an earlier ESim run with overwrite
    ESIM_CHECK(isEmptyFolder(dir_) || (overwrite_ && isEsimRunFolder(dir_)));
    fs::remove_all(dir_);
  }
  fs::rename(partial_, dir_);
}

void RunOutput::discard() {
  std::error_code ec;
  if (isEsimRunFolder(partial_)) fs::remove_all(partial_, ec);
}

std::filesystem::path defaultRunFolder(const std::string& scenarioName) {
  std::string folder;
  for (const char c : scenarioName) {
    const bool keep = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                      c == '-' || c == '_' || c == '.';
    folder += keep ? c : '_';
  }
  for (char& c : folder) {  // leading dots: ".", ".." or a hidden folder
    if (c != '.') break;
    c = '_';
  }
  return fs::path("out") / (folder.empty() ? std::string("unnamed") : folder);
}

void createOutputFolder(const fs::path& dir, const std::string& option) {
  std::error_code ec;
  ESIM_VERIFY(!fs::exists(dir, ec) || fs::is_directory(dir, ec),
              option + ": '" + dir.string() + "' is a file; expected a folder");
  fs::create_directories(dir, ec);
  ESIM_VERIFY(!ec, option + ": cannot create the folder '" + dir.string() + "': " + ec.message());
}

void writeFileAtomic(const fs::path& path, const std::string& text) {
  const fs::path tmp = path.string() + ".tmp" + std::to_string(::getpid());
  std::error_code ec;
  {
    std::ofstream os(tmp, std::ios::binary);
    os << text;
    os.flush();
    if (!os.good()) {
      fs::remove(tmp, ec);
      throw Error(path.string() + ": write failed (disk full?)", ErrorKind::Run);
    }
  }
  fs::rename(tmp, path, ec);
  if (ec) {
    const std::string why = ec.message();
    fs::remove(tmp, ec);
    throw Error(path.string() + ": cannot replace it: " + why, ErrorKind::Run);
  }
}

}  // namespace esim::app
