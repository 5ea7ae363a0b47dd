// memory_room_test.cpp - the memory a run may take: the machine's, a memory cgroup's limit
// (v1 and v2, the tightest group above the process, a container's own root), a sweep
// worker's share (tools/app/memory_room.cpp). Each case writes the /proc and /sys files it
// reads into a scratch folder standing for "/".
#include "tools/app/memory_room.h"

#include <gtest/gtest.h>
#include <malloc.h>
#include <sys/prctl.h>
#include <sys/resource.h>

#include <cstdlib>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "tests/scratch_dir_util.h"

namespace esim::app {
namespace {

namespace fs = std::filesystem;

std::string readFile(const fs::path& p) {
  std::ifstream in(p);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

class MemoryRoomTest : public test::ScratchDirTest {
 protected:
  void write(const std::string& rel, const std::string& text) {
    const fs::path p = root_ / rel;
    fs::create_directories(p.parent_path());
    std::ofstream(p) << text;
  }
  // 10 GB available and 2 GB of swap free (MemAvailable and SwapFree are in kB)
  void machine() {
    write("proc/meminfo",
          "MemTotal:       24683548 kB\nMemAvailable:   9765625 kB\nSwapFree:       1953125 kB\n");
  }
};

constexpr double kMachine = (9765625.0 + 1953125.0) * 1024.0;  // 12.0 GB

TEST_F(MemoryRoomTest, WithoutACgroupLimitItIsTheMachinesAvailableMemoryAndSwap) {
  machine();
  write("proc/self/cgroup", "4:memory:/job_1\n3:cpuset:/\n0::/\n");
  write("sys/fs/cgroup/memory/memory.limit_in_bytes", "9223372036854771712\n");
  write("sys/fs/cgroup/memory/job_1/memory.limit_in_bytes", "9223372036854771712\n");
  write("sys/fs/cgroup/memory/job_1/memory.usage_in_bytes", "1000000\n");
  const MemoryRoom r = memoryRoom(root_, 1);
  EXPECT_DOUBLE_EQ(r.bytes, kMachine);
  EXPECT_TRUE(r.cgroup.empty()) << r.cgroup;
  EXPECT_EQ(r.boundBy, "the machine has 12.00 GB available (MemAvailable + SwapFree)");
}

TEST_F(MemoryRoomTest, ACgroupV1LimitLeavesItsLimitLessWhatIsUsedButReclaimable) {
  machine();
  write("proc/self/cgroup", "5:cpu,memory:/slurm/job_1\n");
  const std::string job = "sys/fs/cgroup/memory/slurm/job_1/";
  write(job + "memory.limit_in_bytes", "1000000000\n");
  write(job + "memory.usage_in_bytes", "400000000\n");
  write(job + "memory.stat", "cache 150000000\ntotal_inactive_file 100000000\n");
  const MemoryRoom r = memoryRoom(root_, 1);
  EXPECT_DOUBLE_EQ(r.bytes, 1e9 - 4e8 + 1e8);
  EXPECT_EQ(r.cgroup, root_ / job.substr(0, job.size() - 1));
  EXPECT_DOUBLE_EQ(r.cgroupLimitBytes, 1e9);
  EXPECT_NE(r.boundBy.find("its memory cgroup " + r.cgroup.string() + " has 0.70 GB left"),
            std::string::npos)
      << r.boundBy;
}

TEST_F(MemoryRoomTest, TheTightestGroupAboveTheProcessSetsIt) {
  machine();
  write("proc/self/cgroup", "0::/user.slice/job\n");
  write("sys/fs/cgroup/user.slice/job/memory.max", "max\n");
  write("sys/fs/cgroup/user.slice/job/memory.current", "500000000\n");
  write("sys/fs/cgroup/user.slice/memory.max", "2000000000\n");
  write("sys/fs/cgroup/user.slice/memory.current", "600000000\n");
  write("sys/fs/cgroup/user.slice/memory.stat", "active_file 5\ninactive_file 100000000\n");
  const MemoryRoom r = memoryRoom(root_, 1);
  EXPECT_DOUBLE_EQ(r.bytes, 2e9 - 6e8 + 1e8);
  EXPECT_EQ(r.cgroup, root_ / "sys/fs/cgroup/user.slice");
  // a looser child under a tighter parent: the parent still decides
  write("sys/fs/cgroup/user.slice/job/memory.max", "2200000000\n");
  EXPECT_DOUBLE_EQ(memoryRoom(root_, 1).bytes, 1.5e9);
  // a tighter child
  write("sys/fs/cgroup/user.slice/job/memory.max", "800000000\n");
  EXPECT_DOUBLE_EQ(memoryRoom(root_, 1).bytes, 3e8);
  EXPECT_EQ(memoryRoom(root_, 1).cgroup, root_ / "sys/fs/cgroup/user.slice/job");
}

TEST_F(MemoryRoomTest, AContainerSeesItsOwnGroupAsTheRoot) {
  // /proc/self/cgroup names the host's path, which is not mounted inside the container
  machine();
  write("proc/self/cgroup", "0::/docker/0123abcd\n");
  write("sys/fs/cgroup/memory.max", "300000000\n");
  write("sys/fs/cgroup/memory.current", "100000000\n");
  const MemoryRoom r = memoryRoom(root_, 1);
  EXPECT_DOUBLE_EQ(r.bytes, 2e8);
  EXPECT_EQ(r.cgroup, root_ / "sys/fs/cgroup");
}

TEST_F(MemoryRoomTest, ALimitAboveTheMachinesMemoryLeavesTheMachines) {
  machine();
  write("proc/self/cgroup", "0::/big\n");
  write("sys/fs/cgroup/big/memory.max", "64000000000\n");
  write("sys/fs/cgroup/big/memory.current", "1000\n");
  const MemoryRoom r = memoryRoom(root_, 1);
  EXPECT_DOUBLE_EQ(r.bytes, kMachine);
  EXPECT_TRUE(r.cgroup.empty());
}

TEST_F(MemoryRoomTest, SweepWorkersShareIt) {
  machine();
  const MemoryRoom r = memoryRoom(root_, 4);
  EXPECT_DOUBLE_EQ(r.bytes, kMachine / 4);
  EXPECT_NE(r.boundBy.find("; one of 4 sweep workers, 3.00 GB each"), std::string::npos)
      << r.boundBy;
}

TEST_F(MemoryRoomTest, UnreadableFilesLeaveItUnknownOrUnbounded) {
  EXPECT_LT(memoryRoom(root_, 1).bytes, 0);  // no /proc/meminfo: not Linux
  machine();
  write("proc/self/cgroup", "garbage\n4:memory\n0::/g\n");
  write("sys/fs/cgroup/g/memory.max", "lots\n");
  EXPECT_DOUBLE_EQ(memoryRoom(root_, 1).bytes, kMachine);
}

// A run in a v1 group limited to 1 GB whose usage grows between frames: the guard stops it
// once the room left is under 32 MB + 1.5 x the largest growth of a frame + the largest
// transient (a new peak's height above the resident memory after the frame)
class MemoryGuardTest : public MemoryRoomTest {
 protected:
  void SetUp() override {
    MemoryRoomTest::SetUp();
    machine();
    write("proc/self/cgroup", "4:memory:/job\n");
    write(kJob + "memory.limit_in_bytes", "1000000000\n");
    write("proc/self/clear_refs", "");  // the guard sets the peak back through it
  }
  // the group's usage [bytes], the process's resident memory and its peak [kB]
  void used(double bytes, long residentKb, long peakKb) {
    write(kJob + "memory.usage_in_bytes", std::to_string(static_cast<long long>(bytes)) + "\n");
    write("proc/self/status", "VmHWM:\t" + std::to_string(peakKb) + " kB\nVmRSS:\t" +
                                  std::to_string(residentKb) + " kB\n");
  }
  const std::string kJob = "sys/fs/cgroup/memory/job/";
};

TEST_F(MemoryGuardTest, StopsWhenTheRoomLeftIsUnderWhatTheNextFrameMayTake) {
  MemoryGuard guard(root_);
  used(500e6, 400000, 450000);  // the start: the set-up's own peak is not a frame's transient
  EXPECT_EQ(guard.check(), "");
  EXPECT_DOUBLE_EQ(guard.reserveBytes(), 32e6);
  used(600e6, 500000, 500000);  // a frame took 100 MB
  EXPECT_EQ(guard.check(), "");
  EXPECT_DOUBLE_EQ(guard.reserveBytes(), 32e6 + 150e6);
  used(650e6, 550000, 560000);  // 50 MB, and a new peak 10.24 MB above the resident one
  EXPECT_EQ(guard.check(), "");
  EXPECT_NEAR(guard.reserveBytes(), 32e6 + 150e6 + 10.24e6, 1);
  used(700e6, 600000, 560000);  // 300 MB left, 192 MB reserve
  EXPECT_EQ(guard.check(), "");
  used(810e6, 710000, 710000);  // 190 MB left, under 32 + 1.5 x 110 + 10 = 207 MB
  const std::string why = guard.check();
  EXPECT_EQ(why.rfind("memory: its memory cgroup " + (root_ / "sys/fs/cgroup/memory/job").string() +
                          " has 190 MB left of 1000 MB, under the 207 MB this run keeps in "
                          "reserve (32 MB, 1.5 times the 110 MB the hungriest frame took, and 10 "
                          "MB a frame held only for a while); it stopped here",
                      0),
            0u)
      << why;
  EXPECT_NE(why.find("more memory (Slurm --mem"), std::string::npos) << why;
  EXPECT_DOUBLE_EQ(guard.minRoomBytes(), 190e6);
  EXPECT_DOUBLE_EQ(guard.peakResidentBytes(), 710000 * 1024.0);
  EXPECT_EQ(readFile(root_ / "proc/self/clear_refs"), "5");  // the peak set back each time
}

// memory given back after a check (a cache cut): the peak before it is no frame's transient,
// and the next frame's growth counts from the room after it
TEST_F(MemoryGuardTest, MemoryGivenBackIsNoTransientAndGrowthCountsFromAfterIt) {
  MemoryGuard guard(root_);
  used(800e6, 700000, 700000);  // 200 MB left
  EXPECT_EQ(guard.check(), "");
  used(500e6, 400000, 700000);  // 300 MB given back: the kernel's peak still says 700
  guard.released();
  EXPECT_EQ(readFile(root_ / "proc/self/clear_refs"), "5");
  used(550e6, 450000, 450000);  // the next frame: 50 MB more, no transient
  EXPECT_EQ(guard.check(), "");
  EXPECT_DOUBLE_EQ(guard.reserveBytes(), 32e6 + 1.5 * 50e6);
}

// without /proc/self/clear_refs the peak cannot be set back: a peak from before memory was
// given back is not taken for a frame's transient
TEST_F(MemoryGuardTest, APeakThatCannotBeSetBackIsNoTransient) {
  fs::remove(root_ / "proc/self/clear_refs");
  MemoryGuard guard(root_);
  used(500e6, 400000, 900000);
  EXPECT_EQ(guard.check(), "");
  used(500e6, 400000, 950000);
  EXPECT_EQ(guard.check(), "");
  EXPECT_DOUBLE_EQ(guard.reserveBytes(), 32e6);
  EXPECT_FALSE(fs::exists(root_ / "proc/self/clear_refs"));  // never created
}

TEST_F(MemoryGuardTest, ReclaimablePageCacheAndFreedMemoryCountAsRoom) {
  MemoryGuard guard(root_);
  used(900e6, 400000, 400000);
  write(kJob + "memory.stat", "total_inactive_file 300000000\n");  // 400 MB left
  EXPECT_EQ(guard.check(), "");
  used(700e6, 400000, 400000);  // memory freed: no growth, the reserve stays 32 MB
  EXPECT_EQ(guard.check(), "");
  EXPECT_DOUBLE_EQ(guard.reserveBytes(), 32e6);
  used(1000e6, 400000, 400000);  // 300 MB taken, 300 MB of cache left to reclaim: 300 < 482
  EXPECT_NE(guard.check(), "");
}

TEST_F(MemoryGuardTest, WithoutAnyLimitItIsTheMachinesMemoryAndUnknownNeverStops) {
  MemoryGuard none(root_ / "nothing");  // no /proc: the room is unknown
  EXPECT_EQ(none.check(), "");
  EXPECT_EQ(none.check(), "");
  EXPECT_LT(none.minRoomBytes(), 0);
  write("proc/self/cgroup", "0::/\n");
  MemoryGuard machineOnly(root_);
  fs::remove(root_ / kJob / "memory.limit_in_bytes");
  EXPECT_EQ(machineOnly.check(), "");
  EXPECT_DOUBLE_EQ(machineOnly.minRoomBytes(), kMachine);
  write("proc/meminfo", "MemAvailable:   20000 kB\nSwapFree:       0 kB\n");  // 20.48 MB
  const std::string why = machineOnly.check();
  EXPECT_EQ(why.rfind("memory: the machine has 20 MB available, under the ", 0), 0u) << why;
}

// each check bounds what the next frame may add to the address space: RLIMIT_AS at what is
// mapped now + the room left - the 32 MB kept for the reports, said by frameBound(); an
// allocation past it is refused, one within it given; unbound() and the guard's end put the
// bound before it back
TEST_F(MemoryGuardTest, EachCheckBoundsWhatTheNextFrameMayMap) {
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
  GTEST_SKIP() << "the sanitizers map terabytes: no address-space bound under them";
#else
  const auto soft = [] {
    rlimit l{};
    EXPECT_EQ(getrlimit(RLIMIT_AS, &l), 0);
    return l.rlim_cur;
  };
  const auto mappedBytes = [] {  // VmSize of this process
    std::ifstream in("/proc/self/status");
    std::string line;
    while (std::getline(in, line))
      if (line.rfind("VmSize:", 0) == 0) return 1024.0 * std::stod(line.substr(7));
    return -1.0;
  };
  const rlim_t before = soft();
  {
    MemoryGuard guard(root_);
    EXPECT_EQ(guard.frameBound(), "");
    used(700e6, 400000, 400000);  // 300 MB left
    EXPECT_EQ(guard.check(), "");
    EXPECT_NEAR(static_cast<double>(soft()), mappedBytes() + 268e6, 8e6);
    const std::string group = (root_ / "sys/fs/cgroup/memory/job").string();
    EXPECT_EQ(guard.frameBound(), "a frame may map 268 MB more: its memory cgroup " + group +
                                      " has 300 MB left of "
                                      "1000 MB");
    EXPECT_THROW(std::vector<char>(static_cast<std::size_t>(400e6)), std::bad_alloc);
    EXPECT_NO_THROW(std::vector<char>(static_cast<std::size_t>(100e6)));
    guard.unbound();
    EXPECT_EQ(soft(), before);
    EXPECT_EQ(guard.frameBound(), "");
    EXPECT_EQ(guard.check(), "");  // bounded again
    EXPECT_NE(soft(), before);
  }
  EXPECT_EQ(soft(), before);
  {
    MemoryGuard guard(root_);
    used(900e6, 400000, 400000);  // 100 MB left: 68 MB more
    EXPECT_EQ(guard.check(), "");
    EXPECT_EQ(guard.frameBound(), "a frame may map 68 MB more: its memory cgroup " +
                                      (root_ / "sys/fs/cgroup/memory/job").string() +
                                      " has 100 MB left of 1000 MB");
    EXPECT_THROW(std::vector<char>(static_cast<std::size_t>(100e6)), std::bad_alloc);
  }
  EXPECT_EQ(soft(), before);
  EXPECT_NO_THROW(std::vector<char>(static_cast<std::size_t>(400e6)));
#endif
}

TEST(MemoryShare, OnlyAPositiveCountIsAShare) {
  const char* before = std::getenv("ESIM_MEMORY_SHARE");
  const std::string saved = before ? before : "";
  for (const auto& [value, share] : std::vector<std::pair<std::string, int>>{
           {"3", 3}, {"1", 1}, {"0", 1}, {"-2", 1}, {"2x", 1}, {"", 1}, {"99999", 1}}) {
    ::setenv("ESIM_MEMORY_SHARE", value.c_str(), 1);
    EXPECT_EQ(memoryShareFromEnvironment(), share) << "'" << value << "'";
  }
  ::unsetenv("ESIM_MEMORY_SHARE");
  EXPECT_EQ(memoryShareFromEnvironment(), 1);
  if (before) ::setenv("ESIM_MEMORY_SHARE", saved.c_str(), 1);
}

// transparent huge pages off for the process (what its threads inherit), unless
// ESIM_ALLOW_THP=1; the note for timing.json says which
TEST(TransparentHugePages, AreOffUnlessAllowed) {
  unsetenv("ESIM_ALLOW_THP");
  ASSERT_EQ(prctl(PR_SET_THP_DISABLE, 0, 0, 0, 0), 0);
  disableTransparentHugePages();
  EXPECT_EQ(prctl(PR_GET_THP_DISABLE, 0, 0, 0, 0), 1);
  EXPECT_EQ(transparentHugePagesNote(), "disabled (PR_SET_THP_DISABLE)");

  ASSERT_EQ(prctl(PR_SET_THP_DISABLE, 0, 0, 0, 0), 0);
  setenv("ESIM_ALLOW_THP", "1", 1);
  disableTransparentHugePages();
  EXPECT_EQ(prctl(PR_GET_THP_DISABLE, 0, 0, 0, 0), 0);
  EXPECT_EQ(transparentHugePagesNote(), "allowed (ESIM_ALLOW_THP=1)");
  setenv("ESIM_ALLOW_THP", "yes", 1);  // only "1" allows them
  disableTransparentHugePages();
  EXPECT_EQ(prctl(PR_GET_THP_DISABLE, 0, 0, 0, 0), 1);
  unsetenv("ESIM_ALLOW_THP");
}

// blocks up to 256 MiB come from the heap (glibc would map one of 200 MiB on its own), larger
// ones still get their own mapping; ESIM_DEFAULT_MALLOC=1 or GLIBC_TUNABLES leave glibc's
// defaults. Not under the sanitizers, whose allocators take no mallopt.
#if !defined(__SANITIZE_ADDRESS__) && !defined(__SANITIZE_THREAD__)
TEST(Malloc, LargeBlocksComeFromTheHeapUnlessDefaultsAreAsked) {
  const char* tunables = std::getenv("GLIBC_TUNABLES");
  const std::string saved = tunables ? tunables : "";
  unsetenv("GLIBC_TUNABLES");
  unsetenv("ESIM_DEFAULT_MALLOC");
  keepLargeBlocksInTheHeap();
  EXPECT_EQ(mallocNote(), "blocks up to 256 MiB from the heap, up to 64 MiB kept free at its top");
  const size_t mapped = mallinfo2().hblks;
  auto* p = static_cast<volatile char*>(std::malloc(200 << 20));
  ASSERT_NE(p, nullptr);
  p[0] = 1;
  EXPECT_EQ(mallinfo2().hblks, mapped) << "a 200 MiB block had a mapping of its own";
  auto* q = static_cast<volatile char*>(std::malloc(300 << 20));
  ASSERT_NE(q, nullptr);
  q[0] = 1;
  EXPECT_EQ(mallinfo2().hblks, mapped + 1);
  std::free(const_cast<char*>(q));
  std::free(const_cast<char*>(p));
  setenv("ESIM_DEFAULT_MALLOC", "1", 1);
  keepLargeBlocksInTheHeap();
  EXPECT_EQ(mallocNote(), "glibc's defaults (ESIM_DEFAULT_MALLOC=1)");
  unsetenv("ESIM_DEFAULT_MALLOC");
  setenv("GLIBC_TUNABLES", "glibc.malloc.mmap_threshold=1048576", 1);
  keepLargeBlocksInTheHeap();
  EXPECT_EQ(mallocNote(), "glibc's defaults or GLIBC_TUNABLES");
  if (saved.empty())
    unsetenv("GLIBC_TUNABLES");
  else
    setenv("GLIBC_TUNABLES", saved.c_str(), 1);
}
#endif

}  // namespace
}  // namespace esim::app
