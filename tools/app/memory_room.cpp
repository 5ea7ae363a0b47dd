// memory_room.cpp - see memory_room.h
#include "tools/app/memory_room.h"

#include <fcntl.h>
#include <malloc.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>
#include <utility>
#include <vector>

namespace esim::app {
namespace fs = std::filesystem;

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
// v1 writes "no limit" as PAGE_COUNTER_MAX pages (9223372036854771712 with 4 KiB pages)
constexpr double kUnlimitedV1 = 1e18;

std::string gAddressSpaceBound;  // what boundAddressSpace set (addressSpaceBound)
std::string gHugePages;          // what disableTransparentHugePages did
std::string gMalloc;             // what keepLargeBlocksInTheHeap did
int gWatcherPipe = -1;           // watchOutOfMemory's write end, held by the watched process

// a "Key:   N kB" line of a /proc file, in bytes (-1 if absent)
double procBytes(const fs::path& file, const std::string& key) {
  std::ifstream in(file);
  std::string line;
  while (std::getline(in, line))
    if (line.rfind(key + ":", 0) == 0) {
      std::istringstream fields(line.substr(key.size() + 1));
      double kb = -1;
      fields >> kb;
      return kb * 1024.0;
    }
  return -1;
}

// the first word of a cgroup file as bytes: "max" is +inf; NaN when absent or unreadable
double cgroupValue(const fs::path& file) {
  std::ifstream in(file);
  std::string word;
  if (!(in >> word)) return std::nan("");
  if (word == "max") return kInf;
  char* end = nullptr;
  const double v = std::strtod(word.c_str(), &end);
  return end && *end == '\0' ? v : std::nan("");
}

// N of a "key N" line (memory.stat, memory.events, memory.oom_control, /proc/vmstat), or
// `absent`
double keyedValue(const fs::path& file, const std::string& key, double absent) {
  std::ifstream in(file);
  std::string k;
  double v = 0;
  while (in >> k >> v)
    if (k == key) return v;
  return absent;
}

std::string gigabytes(double bytes) {
  char b[32];
  std::snprintf(b, sizeof b, "%.2f GB", bytes / 1e9);
  return b;
}

struct CgroupRoom {
  double bytes = kInf;
  fs::path dir;       // the group whose limit leaves the least
  double limit = -1;  // its limit
};

// the memory hierarchies of a /proc/PID/cgroup file: {v2, path}, from "0::/path" (v2) and
// "N:memory:/path" or "N:cpu,memory:/path" (v1)
std::vector<std::pair<bool, std::string>> memoryHierarchies(const fs::path& cgroupFile) {
  std::vector<std::pair<bool, std::string>> found;
  std::ifstream groups(cgroupFile);
  std::string line;
  while (std::getline(groups, line)) {
    const size_t a = line.find(':'), b = a == std::string::npos ? a : line.find(':', a + 1);
    if (b == std::string::npos) continue;
    const std::string controllers = line.substr(a + 1, b - a - 1), rel = line.substr(b + 1);
    if (controllers.empty())
      found.emplace_back(true, rel);
    else if (("," + controllers + ",").find(",memory,") != std::string::npos)
      found.emplace_back(false, rel);
  }
  return found;
}

// the least room left by the memory limits of the group at rel under mount and of every
// group above it (a namespaced container sees its own group as mount's root: rel is then
// not under mount, and the walk starts at the root)
void walkGroups(const fs::path& mount, const std::string& rel, bool v2, CgroupRoom& best) {
  std::error_code ec;
  if (!fs::is_directory(mount, ec)) return;
  fs::path dir = mount / fs::path(rel).relative_path();
  if (!fs::is_directory(dir, ec)) dir = mount;
  for (;;) {
    const double limit = cgroupValue(dir / (v2 ? "memory.max" : "memory.limit_in_bytes"));
    if (std::isfinite(limit) && (v2 || limit < kUnlimitedV1)) {
      double used = cgroupValue(dir / (v2 ? "memory.current" : "memory.usage_in_bytes"));
      if (std::isnan(used)) used = 0;
      // page cache the kernel reclaims before it kills counts as room
      used -= keyedValue(dir / "memory.stat", v2 ? "inactive_file" : "total_inactive_file", 0);
      const double room = std::max(0.0, limit - std::max(0.0, used));
      if (room < best.bytes) best = {room, dir, limit};
    }
    if (dir == mount || !dir.has_relative_path()) break;
    const fs::path up = dir.parent_path();
    if (up.string().size() < mount.string().size()) break;
    dir = up;
  }
}

}  // namespace

MemoryRoom memoryRoom(const fs::path& root, int share) {
  MemoryRoom r;
  const double available = procBytes(root / "proc/meminfo", "MemAvailable");
  if (available < 0) return r;  // not Linux's /proc
  const double swap = std::max(0.0, procBytes(root / "proc/meminfo", "SwapFree"));
  r.bytes = available + swap;
  r.boundBy = "the machine has " + gigabytes(r.bytes) + " available (MemAvailable + SwapFree)";
  CgroupRoom best;
  for (const auto& [v2, rel] : memoryHierarchies(root / "proc/self/cgroup"))
    walkGroups(root / (v2 ? "sys/fs/cgroup" : "sys/fs/cgroup/memory"), rel, v2, best);
  if (best.bytes < r.bytes) {
    r.bytes = best.bytes;
    r.boundBy = "its memory cgroup " + best.dir.string() + " has " + gigabytes(r.bytes) + " left";
    r.cgroup = best.dir;
    r.cgroupLimitBytes = best.limit;
  }
  if (share > 1) {
    r.bytes /= share;
    r.boundBy +=
        "; one of " + std::to_string(share) + " sweep workers, " + gigabytes(r.bytes) + " each";
  }
  return r;
}

MemoryGuard::MemoryGuard(fs::path root) : root_(std::move(root)) {}

namespace {
constexpr double kGuardMarginBytes = 32e6;  // the reports and the video's end
constexpr double kGuardDropFactor = 1.5;    // the next frame may take more than any before

std::string mb(double bytes) { return std::to_string(std::lround(bytes / 1e6)) + " MB"; }

// where the room is, for messages: "its memory cgroup DIR has 47 MB left of 300 MB"
std::string whereRoom(const MemoryRoom& room) {
  return room.cgroup.empty() ? "the machine has " + mb(room.bytes) + " available"
                             : "its memory cgroup " + room.cgroup.string() + " has " +
                                   mb(room.bytes) + " left of " + mb(room.cgroupLimitBytes);
}
}  // namespace

void MemoryGuard::boundNextFrame(const MemoryRoom& room) {
#if !defined(__SANITIZE_ADDRESS__) && !defined(__SANITIZE_THREAD__)
  // what this process maps (the real one: root_ stands for "/" in tests, for the room only)
  const double mapped = procBytes("/proc/self/status", "VmSize");
  rlimit limit{};
  if (mapped < 0 || room.bytes < 0 || getrlimit(RLIMIT_AS, &limit) != 0) return;
  if (!haveStartLimit_) {
    startLimit_ = limit.rlim_cur;
    haveStartLimit_ = true;
  }
  const int share = memoryShareFromEnvironment();
  const double more = std::max(0.0, room.bytes / share - kGuardMarginBytes);
  double bound = mapped + more;
  if (startLimit_ != RLIM_INFINITY) bound = std::min(bound, static_cast<double>(startLimit_));
  if (limit.rlim_max != RLIM_INFINITY) bound = std::min(bound, static_cast<double>(limit.rlim_max));
  limit.rlim_cur = static_cast<rlim_t>(bound);
  if (setrlimit(RLIMIT_AS, &limit) != 0) return;
  frameBound_ = "a frame may map " + mb(bound - mapped) + " more: " + whereRoom(room) +
                (share > 1 ? " (this run's share: 1 of " + std::to_string(share) + ")" : "");
#else
  (void)room;
#endif
}

void MemoryGuard::unbound() {
  if (!haveStartLimit_) return;
  rlimit limit{};
  if (getrlimit(RLIMIT_AS, &limit) != 0) return;
  limit.rlim_cur = static_cast<rlim_t>(startLimit_);
  if (setrlimit(RLIMIT_AS, &limit) == 0) frameBound_.clear();
}

double MemoryGuard::reserveBytes() const {
  return kGuardMarginBytes + kGuardDropFactor * maxDrop_ + maxTransient_;
}

std::string MemoryGuard::check() {
  if (root_.empty()) return "";
  const MemoryRoom room = memoryRoom(root_, 1);
  if (room.bytes < 0) return "";
  if (lastRoom_ >= 0) maxDrop_ = std::max(maxDrop_, lastRoom_ - room.bytes);
  lastRoom_ = room.bytes;
  minRoom_ = minRoom_ < 0 ? room.bytes : std::min(minRoom_, room.bytes);
  const double peak = procBytes(root_ / "proc/self/status", "VmHWM");
  const double resident = procBytes(root_ / "proc/self/status", "VmRSS");
  if (peak >= 0 && resident >= 0) {
    peakSeen_ = std::max(peakSeen_, peak);
    // the peak since the last check above the resident memory now: what the frame held
    // for a while (not at the first check, whose peak is the set-up's)
    if (peakReset_) maxTransient_ = std::max(maxTransient_, peak - resident);
    // the kernel's peak (VmHWM) set back to the resident memory, so that the next check
    // sees the next frame's peak alone, not one from before memory was given back
    resetPeak();
  }
  const double reserve = reserveBytes();
  if (room.bytes >= reserve) {
    boundNextFrame(room);
    return "";
  }
  return "memory: " + whereRoom(room) + ", under the " + mb(reserve) +
         " this run keeps in reserve (" + mb(kGuardMarginBytes) + ", 1.5 times the " +
         mb(maxDrop_) + " the hungriest frame took, and " + mb(maxTransient_) +
         " a frame held only for a while); it stopped here, before the kernel's out-of-memory "
         "killer would end it without its reports. It needs more: a coarser mesh "
         "(mesh.slab.nodes, mesh.file.cell_size_m), fewer phases, another electric strategy, or "
         "more memory (Slurm --mem, docker --memory)";
}

void MemoryGuard::resetPeak() {
  const int fd = ::open((root_ / "proc/self/clear_refs").c_str(), O_WRONLY | O_CLOEXEC);
  peakReset_ = fd >= 0 && ::write(fd, "5", 1) == 1;
  if (fd >= 0) ::close(fd);
}

void MemoryGuard::released() {
  if (root_.empty()) return;
  const MemoryRoom room = memoryRoom(root_, 1);
  if (room.bytes >= 0) lastRoom_ = room.bytes;
  if (peakReset_) resetPeak();
  boundNextFrame(room);
}

fs::path memoryRootFromEnvironment() {
  const char* v = std::getenv("ESIM_MEMORY_ROOT");
  return v && *v ? fs::path(v) : fs::path("/");
}

int memoryShareFromEnvironment() {
  const char* v = std::getenv("ESIM_MEMORY_SHARE");
  if (!v) return 1;
  char* end = nullptr;
  const long n = std::strtol(v, &end, 10);
  return end != v && *end == '\0' && n >= 1 && n <= 4096 ? static_cast<int>(n) : 1;
}

void boundAddressSpace() {
#if !defined(__SANITIZE_ADDRESS__) && !defined(__SANITIZE_THREAD__)
  const double mapped = procBytes("/proc/self/status", "VmSize");
  const MemoryRoom room = memoryRoom("/", memoryShareFromEnvironment());
  if (mapped < 0 || room.bytes < 0) return;  // not Linux's /proc: leave it
  const double bound = mapped + room.bytes + 4.0 * (1 << 30);
  rlimit limit{};
  if (getrlimit(RLIMIT_AS, &limit) != 0) return;
  if (limit.rlim_cur != RLIM_INFINITY && static_cast<double>(limit.rlim_cur) <= bound) return;
  limit.rlim_cur = static_cast<rlim_t>(bound);
  if (limit.rlim_max != RLIM_INFINITY) limit.rlim_cur = std::min(limit.rlim_cur, limit.rlim_max);
  if (setrlimit(RLIMIT_AS, &limit) != 0) return;
  gAddressSpaceBound = "esim bounded itself to " + gigabytes(static_cast<double>(limit.rlim_cur)) +
                       " of address space: " + room.boundBy;
#endif
}

const std::string& addressSpaceBound() { return gAddressSpaceBound; }

void disableTransparentHugePages() {
  const char* allow = std::getenv("ESIM_ALLOW_THP");
  if (allow && std::strcmp(allow, "1") == 0) {
    gHugePages = "allowed (ESIM_ALLOW_THP=1)";
    return;
  }
  gHugePages = prctl(PR_SET_THP_DISABLE, 1, 0, 0, 0) == 0
                   ? "disabled (PR_SET_THP_DISABLE)"
                   : std::string("left as the system sets them: PR_SET_THP_DISABLE failed: ") +
                         std::strerror(errno);
}

const std::string& transparentHugePagesNote() { return gHugePages; }

void keepLargeBlocksInTheHeap() {
  const char* keep = std::getenv("ESIM_DEFAULT_MALLOC");
  if (keep && std::strcmp(keep, "1") == 0) {
    gMalloc = "glibc's defaults (ESIM_DEFAULT_MALLOC=1)";
    return;
  }
  if (std::getenv("GLIBC_TUNABLES")) {
    gMalloc = "glibc's defaults or GLIBC_TUNABLES";
    return;
  }
  // blocks up to 256 MiB: a coarse region's factor at 50k nodes holds 5-25 M entries of L
  // (40-200 MB of values, README "Region builds without page faults")
  constexpr int kHeapBytes = 256 << 20, kTrimBytes = 64 << 20;
  gMalloc = mallopt(M_MMAP_THRESHOLD, kHeapBytes) == 1 && mallopt(M_TRIM_THRESHOLD, kTrimBytes) == 1
                ? "blocks up to " + std::to_string(kHeapBytes >> 20) +
                      " MiB from the heap, up to " + std::to_string(kTrimBytes >> 20) +
                      " MiB kept free at its top"
                : "glibc's defaults (mallopt refused)";
}

const std::string& mallocNote() { return gMalloc; }

namespace {

void markNormalExit() {
  if (gWatcherPipe < 0) return;
  const char mark = 'x';
  while (::write(gWatcherPipe, &mark, 1) < 0 && errno == EINTR) {
  }
}

// The kills of the out-of-memory killer among this process's memory cgroup and the groups
// below it (v2 memory.events, v1 memory.oom_control: "oom_kill N"), else since boot in any
// group (/proc/vmstat), so that a kill elsewhere on the machine is not taken for ours. -1
// when none of these can be read.
double oomKills() {
  for (const auto& [v2, path] : memoryHierarchies("/proc/self/cgroup")) {
    const fs::path rel = fs::path(path).relative_path();
    const double v =
        v2 ? keyedValue(fs::path("/sys/fs/cgroup") / rel / "memory.events", "oom_kill", -1)
           : keyedValue(fs::path("/sys/fs/cgroup/memory") / rel / "memory.oom_control", "oom_kill",
                        -1);
    if (v >= 0) return v;
  }
  return keyedValue("/proc/vmstat", "oom_kill", -1);
}

// the message of the watcher: what ended the process and the memory it could have had
std::string oomMessage() {
  const MemoryRoom room = memoryRoom("/", 1);
  std::string what = "esim: error: the kernel's out-of-memory killer ended esim (signal 9)";
  const double total = procBytes("/proc/meminfo", "MemTotal");
  if (!room.cgroup.empty())
    what += ": its memory cgroup " + room.cgroup.string() + " allows " +
            gigabytes(room.cgroupLimitBytes);
  else if (total > 0)
    what += ": the machine has " + gigabytes(total) + " of memory";
  return what +
         ". It needed more: a coarser mesh (mesh.slab.nodes, mesh.file.cell_size_m), fewer "
         "phases, another electric strategy, or more memory (Slurm --mem, docker --memory). A "
         "run keeps what it wrote so far in DIR.partial: video.mp4.partial plays up to the last "
         "key frame (every 2 s), timing.csv.partial has a row per frame done.\n";
}

}  // namespace

void watchOutOfMemory() {
  const char* off = std::getenv("ESIM_NO_WATCHER");
  if (off && *off && std::string(off) != "0") return;
  const double kills = oomKills();
  if (kills < 0) return;
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0) return;
  const pid_t pid = ::fork();
  if (pid < 0) {
    ::close(fds[0]);
    ::close(fds[1]);
    return;
  }
  if (pid > 0) {  // the watched process: keeps the write end, marks a normal exit
    ::close(fds[0]);
    gWatcherPipe = fds[1];
    std::atexit(markNormalExit);
    return;
  }
  // the watcher: no signal of the group, no stdin/stdout, only the read end
  std::signal(SIGINT, SIG_IGN);
  std::signal(SIGTERM, SIG_IGN);
  std::signal(SIGHUP, SIG_IGN);
  ::close(fds[1]);
  const int null = ::open("/dev/null", O_RDWR);
  if (null >= 0) {
    ::dup2(null, 0);
    ::dup2(null, 1);
    ::close(null);
  }
  char mark = 0;
  ssize_t n = 0;
  while ((n = ::read(fds[0], &mark, 1)) < 0 && errno == EINTR) {
  }
  if (n == 0 && oomKills() > kills) {
    const std::string message = oomMessage();
    [[maybe_unused]] const ssize_t w = ::write(2, message.data(), message.size());
  }
  ::_exit(0);
}

}  // namespace esim::app
