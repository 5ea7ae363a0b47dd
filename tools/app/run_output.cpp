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

// name, or name.tmp<digits> (an atomic write cut short)
std::string withoutTmp(const std::string& name) {
  const size_t at = name.rfind(".tmp");
  if (at == std::string::npos || at + 4 == name.size()) return name;
  for (size_t k = at + 4; k < name.size(); ++k)
    if (name[k] < '0' || name[k] > '9') return name;
  return name.substr(0, at);
}

// true for a file `esim run` writes in the folder `sub` of its output ("" = the top)
bool runFile(const std::string& sub, const std::string& file) {
  const std::string name = withoutTmp(file);
  if (sub.empty())
    for (const char* n :
         {".esim-run", "video.mp4", "video.mp4.partial", "video.mp4.regular.partial", "timing.csv",
          "timing.csv.partial", "timing.json", "trace.json", "scenario.yaml", "hashes.json",
          "summary.txt", "timing.png"})
      if (name == n) return true;
  if (sub == "frames") return isNumberedName(name, "frame_", ".png");
  if (sub == "fields") return isNumberedName(name, "frame_", ".vtu");
  if (sub == "labels") {
    for (const char* n : {"camera.json", "classes.json", "coco.json", "frames.jsonl", "preview.mp4",
                          "preview.mp4.partial", "preview.mp4.regular.partial"})
      if (name == n) return true;
    return isNumberedName(name, "depth_", ".png") || isNumberedName(name, "mask_", ".png");
  }
  if (sub == "compare")  // esim compare's report, its default folder until this session
    return name == "compare.json" || isNumberedName(name, "diff_frame_", ".png");
  return false;
}

// true when another process holds the flock of the folder (an esim run writing it)
bool lockedByAnother(const fs::path& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return false;
  FolderLock probe;  // released at once
  return !probe.tryLock(dir, "-o");
}

std::string anotherRunMessage(const fs::path& dir) {
  return "-o " + dir.string() +
         ": another esim run is writing this folder (its .partial is locked); wait for it to "
         "end or give another folder (nothing was changed)";
}

}  // namespace

bool isNumberedName(const std::string& name, const std::string& prefix, const std::string& suffix) {
  if (name.size() < prefix.size() + 5 + suffix.size() || name.rfind(prefix, 0) != 0 ||
      name.compare(name.size() - suffix.size(), suffix.size(), suffix) != 0)
    return false;
  for (size_t k = prefix.size(); k < name.size() - suffix.size(); ++k)
    if (name[k] < '0' || name[k] > '9') return false;
  return true;
}

std::string foreignEntry(const fs::path& dir) {
  std::error_code ec;
  for (const fs::directory_entry& e : fs::directory_iterator(dir, ec)) {
    const std::string name = e.path().filename().string();
    if (e.is_directory(ec) && !e.is_symlink(ec)) {
      if (name != "frames" && name != "fields" && name != "labels" && name != "compare")
        return name + "/";
      for (const fs::directory_entry& f : fs::directory_iterator(e.path(), ec))
        if (!f.is_regular_file(ec) || f.is_symlink(ec) ||
            !runFile(name, f.path().filename().string()))
          return name + "/" + f.path().filename().string();
    } else if (!e.is_regular_file(ec) || e.is_symlink(ec) || !runFile("", name)) {
      return name;
    }
  }
  return ec ? std::string("(cannot list: ") + ec.message() + ")" : std::string();
}

bool FolderLock::tryLock(const fs::path& dir, const std::string& what) {
  release();
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  ESIM_VERIFY(fd >= 0, what + ": cannot open " + dir.string() + ": " + std::strerror(errno));
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    ::close(fd);
    return false;
  }
  fd_ = fd;
  return true;
}

void FolderLock::release() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

bool isEsimRunFolder(const fs::path& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return false;
  if (fs::exists(dir / kMarker, ec)) return true;
  return fs::exists(dir / "timing.json", ec) && fs::exists(dir / "scenario.yaml", ec) &&
         fs::exists(dir / "summary.txt", ec);
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
  if (fs::exists(partial_, ec)) checkPartial();
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
      const std::string foreign = foreignEntry(dir_);
      ESIM_VERIFY(foreign.empty(), "-o " + dir_.string() + ": --overwrite would delete '" +
                                       foreign +
                                       "', which no ESim run writes; move it away, or give "
                                       "another folder (nothing was changed)");
    }
  }
}

void RunOutput::checkPartial() const {
  if (isEmptyFolder(partial_)) return;
  const bool ours = isEsimRunFolder(partial_);
  const std::string foreign = ours ? foreignEntry(partial_) : std::string();
  ESIM_VERIFY(ours && foreign.empty(),
              partial_.string() + ": exists and is not an ESim run's partial output" +
                  (foreign.empty() ? "" : " (it holds '" + foreign + "')") +
                  "; move it away or give another -o folder (nothing was changed)");
}

void RunOutput::create() {
  ESIM_CHECK(lock_.fd() < 0);
  fs::create_directories(partial_.parent_path());
  bool made = false;  // DIR.partial/ created here (removed again if refused)
  for (int attempt = 0; lock_.fd() < 0; ++attempt) {
    ESIM_VERIFY(attempt < 100, "-o " + dir_.string() + ": " + partial_.string() +
                                   " keeps changing; is another run using it?");
    if (::mkdir(partial_.c_str(), 0777) == 0)
      made = true;
    else
      ESIM_VERIFY(errno == EEXIST, "-o " + dir_.string() + ": cannot create " + partial_.string() +
                                       ": " + std::strerror(errno));
    std::error_code ec;
    if (!fs::is_directory(partial_, ec)) continue;  // renamed away meanwhile
    if (!lock_.tryLock(partial_, "-o " + dir_.string())) throw Error(anotherRunMessage(dir_));
    // still DIR.partial (a run completing renames its own to DIR): else try again
    struct stat locked {};
    struct stat named {};
    if (!(::fstat(lock_.fd(), &locked) == 0 && ::stat(partial_.c_str(), &named) == 0 &&
          locked.st_dev == named.st_dev && locked.st_ino == named.st_ino))
      lock_.release();
  }
  try {
    checkFinal();  // again, under the lock: a run may have completed there since
    checkPartial();
  } catch (...) {
    if (made) {
      std::error_code ec;
      fs::remove(partial_, ec);  // empty, ours
    }
    lock_.release();
    throw;
  }
  // an earlier run's partial output goes; the folder itself stays (it carries the lock)
  for (const fs::directory_entry& e : fs::directory_iterator(partial_)) fs::remove_all(e.path());
  std::ofstream(partial_ / kMarker) << "esim run output (partial until renamed)\n";
}

void RunOutput::commit() {
  std::error_code ec;
  if (fs::exists(dir_, ec)) {
    // checked in the constructor and create(): empty, or an earlier ESim run with overwrite
    ESIM_CHECK(isEmptyFolder(dir_) || (overwrite_ && isEsimRunFolder(dir_)));
    // only what a run writes goes: a file put there since the checks stays, and so does
    // this run, as DIR.partial
    const std::string foreign = foreignEntry(dir_);
    if (!foreign.empty())
      throw Error("-o " + dir_.string() + ": '" + foreign +
                      "' appeared in it during the run and is no ESim run's; the run is "
                      "complete in " +
                      partial_.string() + " (nothing of " + dir_.string() + " was deleted)",
                  ErrorKind::Run);
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

void createOutputFolder(const fs::path& dir, const std::string& option, FolderLock& lock) {
  std::error_code ec;
  ESIM_VERIFY(!fs::exists(dir, ec) || fs::is_directory(dir, ec),
              option + ": '" + dir.string() + "' is a file; expected a folder");
  fs::create_directories(dir, ec);
  ESIM_VERIFY(!ec, option + ": cannot create the folder '" + dir.string() + "': " + ec.message());
  ESIM_VERIFY(lock.tryLock(dir, option), option + ": another esim is writing '" + dir.string() +
                                             "'; give another folder, or wait for it to end "
                                             "(nothing was changed)");
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
