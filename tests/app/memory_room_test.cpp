// memory_room_test.cpp - the memory a run may take: the machine's, a memory cgroup's limit
// (v1 and v2, the tightest group above the process, a container's own root), a sweep
// worker's share (tools/app/memory_room.cpp). Each case writes the /proc and /sys files it
// reads into a scratch folder standing for "/".
#include "tools/app/memory_room.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>
#include <string>

#include "tests/scratch_dir_util.h"

namespace esim::app {
namespace {

namespace fs = std::filesystem;

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

}  // namespace
}  // namespace esim::app
