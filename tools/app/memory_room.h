// memory_room.h - how much memory a run may still take, and esim's bound on its own
// address space.
//
// Linux overcommits memory: a scene too large for the machine is not refused an allocation
// but killed by the kernel once it touches more than there is (signal 9, no message). The
// same happens, sooner, under a memory cgroup's limit: a Slurm job's --mem, a container's
// --memory, systemd-run -p MemoryMax, where /proc/meminfo still shows the whole machine
// (measured: `esim run scenarios/slab_cut.yaml --set mesh.slab.nodes=100000` in a cgroup
// v1 group limited to 700 MB was killed by signal 9 after 5 s, no message). Bounding the
// address space by the room there is makes such an allocation throw std::bad_alloc instead:
// "out of memory", exit 1, as the messages promise.
//
// The room: MemAvailable + SwapFree (/proc/meminfo), at most what every memory cgroup
// above this process has left (v2: memory.max - memory.current + inactive file pages, the
// page cache the kernel reclaims before it kills; v1: memory.limit_in_bytes -
// memory.usage_in_bytes + total_inactive_file), divided among the workers of a sweep
// (ESIM_MEMORY_SHARE=N, set by esim sweep for its children: N runs at once each see the
// whole machine's memory at their start).
#pragma once

#include <filesystem>
#include <string>

namespace esim::app {

struct MemoryRoom {
  double bytes = -1;             // < 0: unknown (no /proc/meminfo)
  std::string boundBy;           // what set it, for messages: "the machine has 24.16 GB available
                                 // (MemAvailable + SwapFree)" or "its memory cgroup DIR has 0.70 GB
                                 // left", then the sweep's share
  std::filesystem::path cgroup;  // the memory cgroup that set it (empty: the machine)
  double cgroupLimitBytes = -1;  // its limit
};

// the room under root (the file system root; tests pass a folder holding proc/meminfo,
// proc/self/cgroup and sys/fs/cgroup/...), divided by share (>= 1)
MemoryRoom memoryRoom(const std::filesystem::path& root, int share);

// the share esim sweep gives its children: ESIM_MEMORY_SHARE as a positive integer, else 1
int memoryShareFromEnvironment();

// Bounds this process's address space (RLIMIT_AS) by what is mapped now, the room
// (memoryRoom("/", memoryShareFromEnvironment())) and 4 GiB for reservations that are never
// touched (thread stacks, malloc arenas). A lower bound already set (ulimit -v) stays. Not
// under the sanitizers, which reserve terabytes of address space. Called once, at start.
void boundAddressSpace();

// Transparent huge pages off for this process and its threads (prctl PR_SET_THP_DISABLE),
// unless ESIM_ALLOW_THP=1. libx264 asks for huge pages (madvise MADV_HUGEPAGE) for its
// frame buffers; on this project's machines (a VM; THP "madvise"), a run with them had the
// structural solve's frames 4-10x slower every ~11 frames, all in user time, with the other
// core idle (measured on slab_cut, `perf record` and /proc/thread-self/schedstat: 3 of 5
// runs with 9-13 such frames of 40-125 ms; with THP off 0 in 5; README, "Frame-time
// spikes"). The frame loop gains nothing from huge pages here. Called once, at start;
// transparentHugePagesNote() says what it did, for timing.json.
void disableTransparentHugePages();
const std::string& transparentHugePagesNote();

// Blocks of up to 256 MiB from malloc's heap rather than a mapping of their own, and up to
// 64 MiB of free heap kept at its top (glibc's M_MMAP_THRESHOLD and M_TRIM_THRESHOLD; by
// default the first grows with the blocks freed up to 32 MiB, the second is twice it), unless
// ESIM_DEFAULT_MALLOC=1 or GLIBC_TUNABLES is set. The local and coarse structural methods
// factorize a region of tens of MB at each build and free the last one: each new mapping
// was zeroed and faulted in page by page (the kernel's page faults were 15 % of a run's
// samples). Measured (README, "Region builds without page faults"): the local and coarse
// methods' p95 in the cut 11-23 % lower, their CPU a frame 5-21 % lower; the default cut
// unchanged, peak memory no higher; 256 rather than 64 MiB (2026-12-06): the coarse method's
// p95 at 50k nodes (region factors of 40-200 MB) 20-35 % lower. Called once, at start; mallocNote()
// says what it did, for timing.json.
void keepLargeBlocksInTheHeap();
const std::string& mallocNote();

// The kernel's out-of-memory killer ends a process with SIGKILL, which it cannot catch: a
// run whose memory grows a little at a time past what its cgroup allows (each allocation
// under the address-space bound) ended with no word ("Killed", exit 137). This forks a
// watcher that waits, on a pipe, for this process to end. An end without the mark written at
// exit() (or a return from main), while the kernel's count of such kills grew (in this
// process's memory cgroup and the groups below it, else /proc/vmstat), is reported on stderr:
// what ended it and the memory it had ("esim: error: the kernel's out-of-memory killer ended
// esim ..."). The exit status stays the kill's (137); esim sweep reads the line from the
// variant's log. The watcher ignores SIGINT, SIGTERM and SIGHUP (a Ctrl-C reaches the whole
// process group), holds no file of the run, and leaves with this process. Call once, at
// start, before any thread or file is opened; ESIM_NO_WATCHER=1 turns it off.
void watchOutOfMemory();

// Between frames, the room a run has left (memoryRoom(root, 1)) against what its frames take.
// A run whose memory grows a frame at a time (the electric column cache, a factor's fill, the
// encoder's buffers) under a memory cgroup passes the address-space bound allocation by
// allocation and is then killed by the kernel, with no reports (measured: `esim run
// scenarios/slab_cut.yaml` in a cgroup v1 group limited to 550 MB, exit 137). check() says when
// the room left is under the reserve
//   32 MB + 1.5 x (the largest drop of the room from one frame to the next) + (the largest
//   transient: how far a frame's peak resident memory rose above its resident memory after
//   it; the kernel's peak, VmHWM, is set back at each check through /proc/self/clear_refs),
// so the run can give memory back or stop after a whole frame and write its reports (exit 1)
// while it still can. A share of the machine or of a group that other processes take counts
// too: the room is what is left, not what this run used.
class MemoryGuard {
 public:
  // root: "/" (tests pass a folder holding proc/meminfo, proc/self/status, proc/self/cgroup
  // and sys/fs/cgroup/...); empty: no guard (check() reads nothing and says nothing). The
  // first check() takes the room it finds as its start.
  explicit MemoryGuard(std::filesystem::path root = "/");
  ~MemoryGuard() { unbound(); }
  MemoryGuard(const MemoryGuard&) = delete;
  MemoryGuard& operator=(const MemoryGuard&) = delete;
  // after a frame: "" while the room is known and over the reserve (or unknown), else why the
  // run stops: "memory: its memory cgroup DIR has 50 MB left of 550 MB, under the 61 MB this
  // run keeps in reserve (...)"
  std::string check();
  // after the run gave memory back (a cache cut): the room and the kernel's peak are taken
  // again, so that the next check measures the next frame from here (the peak before the
  // release is no frame's transient)
  void released();
  // Each check() and released() also bounds what the next frame may add to the address space
  // (RLIMIT_AS): what is mapped now + the room left (its share: ESIM_MEMORY_SHARE) - the 32
  // MB kept for the reports, never above the bound found at the first check. A frame that asks
  // for more than the room (a rebuild's second model, a refactorization's workspace the run
  // has not needed before) gets std::bad_alloc and the run stops with its reports (exit 1),
  // where the kernel's out-of-memory killer ended it with none (measured: `esim run
  // scenarios/slab_cut.yaml --set solvers.rebuild.mode=synchronous` in a cgroup v1 group
  // limited to 330 MB, exit 137 before). The bound counts mappings, not the pages touched: a
  // frame that touches pages mapped before (a malloc arena's reserve) is not bounded by it.
  // Not under the sanitizers (they map terabytes). unbound() (and the destructor) puts the
  // first check's bound back, for the reports.
  void unbound();
  // the bound the last check set, for an out-of-memory message: "a frame may map 85 MB more:
  // its memory cgroup DIR has 117 MB left of 330 MB"; "" when none is set
  const std::string& frameBound() const { return frameBound_; }
  double reserveBytes() const;                      // as of the last check
  double minRoomBytes() const { return minRoom_; }  // the least room seen (< 0: unknown)
  // the largest peak resident memory read (< 0: none). check() sets the kernel's peak back
  // each time (getrusage's ru_maxrss with it), so a run's peak is the larger of the two
  double peakResidentBytes() const { return peakSeen_; }

 private:
  void resetPeak();  // the kernel's peak set back to the resident memory (clear_refs 5)
  void boundNextFrame(const MemoryRoom& room);  // RLIMIT_AS (see unbound)
  std::filesystem::path root_;
  double lastRoom_ = -1;  // the room at the last check (< 0: none yet)
  double minRoom_ = -1;
  double maxDrop_ = 0;            // largest drop of the room between two checks [bytes]
  bool peakReset_ = false;        // the last check set the kernel's peak back (clear_refs 5)
  double maxTransient_ = 0;       // largest VmHWM - VmRSS since such a reset [bytes]
  double peakSeen_ = -1;          // the largest VmHWM read [bytes]
  bool haveStartLimit_ = false;   // startLimit_ read (at the first bound)
  unsigned long startLimit_ = 0;  // RLIMIT_AS's soft limit before the first bound (rlim_t)
  std::string frameBound_;        // what the last bound set ("" none)
};

// the root ESIM_MEMORY_ROOT names (a test's folder standing for "/"), else "/"
std::filesystem::path memoryRootFromEnvironment();

// what boundAddressSpace set, for the out-of-memory messages and timing.json: e.g. "esim
// bounded itself to 1.4 GB of address space: its memory cgroup
// /sys/fs/cgroup/memory/job_12/ has 0.7 GB left"; empty when it set nothing
const std::string& addressSpaceBound();

}  // namespace esim::app
