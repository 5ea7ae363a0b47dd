// source_tree_test.cpp - files of the source tree are found from any working folder
// (tools/app/source_tree.cpp).
#include "tools/app/source_tree.h"

#include <gtest/gtest.h>

#include <filesystem>

namespace esim::app {
namespace {

namespace fs = std::filesystem;

TEST(SourceTree, FindsItsFilesFromAnyWorkingFolder) {
  const fs::path before = fs::current_path();
  fs::current_path(fs::temp_directory_path());
  const fs::path scene = findSourceTreeFile("scenarios/slab_cut.yaml");
  const fs::path script = findSourceTreeFile("tools/plot_timing.py");
  const fs::path missing = findSourceTreeFile("scenarios/no_such_scene.yaml");
  fs::current_path(before);
  EXPECT_TRUE(fs::is_regular_file(scene)) << scene;
  EXPECT_TRUE(fs::equivalent(scene, fs::path(ESIM_SOURCE_DIR) / "scenarios/slab_cut.yaml"));
  EXPECT_TRUE(fs::is_regular_file(script)) << script;
  EXPECT_TRUE(missing.empty()) << missing;
}

}  // namespace
}  // namespace esim::app
