// Tests for sim/io/vtu.cpp: write and read back nodes, tets and fields.
#include "sim/io/vtu.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>

#include "sim/core_error.h"
#include "sim/mesh_slab.h"

namespace esim {
namespace {

std::string tempPath(const std::string& name) {
  return (std::filesystem::temp_directory_path() / ("esim_vtu_test_" + name)).string();
}

TEST(Vtu, RoundTripNodesTetsAndFields) {
  SlabSpec s;
  s.targetNodes = 200;
  const TetMesh m = makeSlab(s);
  VtuField temp{"temperature", 1, {}}, disp{"displacement", 3, {}}, sigma{"conductivity", 1, {}};
  for (int i = 0; i < m.numNodes(); ++i) {
    temp.values.push_back(37.0 + m.nodes[i].x() * 1000.0 + 1e-9 * i);
    for (int c = 0; c < 3; ++c) disp.values.push_back(m.nodes[i][c] * 1e-3);
  }
  for (int e = 0; e < m.numTets(); ++e) sigma.values.push_back(0.144 + e * 1e-6);
  const std::string path = tempPath("roundtrip.vtu");
  writeVtu(path, m, {temp, disp}, {sigma});
  EXPECT_FALSE(std::filesystem::exists(path + ".tmp"));
  const VtuData d = readVtu(path);
  ASSERT_EQ(d.points.size(), m.nodes.size());
  for (int i = 0; i < m.numNodes(); ++i) EXPECT_EQ(d.points[i], m.nodes[i]);  // bit-exact
  EXPECT_EQ(d.tets, m.tets);
  ASSERT_NE(d.findPointField("temperature"), nullptr);
  EXPECT_EQ(d.findPointField("temperature")->values, temp.values);
  EXPECT_EQ(d.findPointField("displacement")->components, 3);
  EXPECT_EQ(d.findPointField("displacement")->values, disp.values);
  EXPECT_EQ(d.findCellField("conductivity")->values, sigma.values);
  std::filesystem::remove(path);
}

TEST(Vtu, RemovedTetsAreLeftOutWithTheirIds) {
  SlabSpec s;
  s.targetNodes = 100;
  TetMesh m = makeSlab(s);
  m.alive[3] = 0;
  VtuField f{"alive", 1, std::vector<double>(m.numTets(), 1.0)};
  f.values[3] = 0;
  const std::string path = tempPath("removed.vtu");
  writeVtu(path, m, {}, {f});
  const VtuData d = readVtu(path);
  EXPECT_EQ(d.tets.size(), m.tets.size() - 1);
  const auto* ids = d.findCellField("tet_id");
  ASSERT_NE(ids, nullptr);
  EXPECT_EQ(ids->values[2], 2.0);
  EXPECT_EQ(ids->values[3], 4.0);
  for (double a : d.findCellField("alive")->values) EXPECT_EQ(a, 1.0);
  std::filesystem::remove(path);
}

// a target that cannot be replaced (a folder) fails with nothing left beside it (the
// temporary file stayed, e.g. assets.tmp of `esim mesh-info ... --vtu assets`)
TEST(Vtu, AFailedWriteLeavesNoTemporaryFile) {
  const std::filesystem::path dir = tempPath("vtu_target_folder.vtu");
  std::filesystem::create_directories(dir);
  std::ofstream(dir.string() + ".tmp") << "a user's file\n";
  SlabSpec spec;
  spec.targetNodes = 50;
  try {
    writeVtu(dir.string(), makeSlab(spec), {}, {});
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(dir.string() + ": cannot write it: "), std::string::npos)
        << e.what();
  }
  int beside = 0;
  for (const auto& entry : std::filesystem::directory_iterator(dir.parent_path()))
    beside += entry.path().filename().string().rfind(dir.filename().string() + ".tmp", 0) == 0;
  EXPECT_EQ(beside, 1) << "a temporary file was left";
  std::ifstream user(dir.string() + ".tmp");
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(user), {}), "a user's file\n");
  std::filesystem::remove_all(dir);
  std::filesystem::remove(dir.string() + ".tmp");
}

TEST(Vtu, BadInputNamesTheFile) {
  try {
    readVtu("/nonexistent/x.vtu");
    FAIL();
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "/nonexistent/x.vtu: file not found");
  }
  // a device (it was read until memory ran out)
  try {
    readVtu("/dev/zero");
    FAIL();
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "/dev/zero: cannot read the .vtu: not a regular file");
  }
  const std::string path = tempPath("garbage.vtu");
  std::ofstream(path) << "hello";
  try {
    readVtu(path);
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), path + ": not a VTK XML UnstructuredGrid file");
  }
  std::filesystem::remove(path);
  // the Points' array has no Name: it was "DataArray '': value 11 is not a number" for the
  // twelfth value
  const std::string nan = tempPath("nan.vtu");
  std::ofstream(nan) << "<VTKFile type=\"UnstructuredGrid\"><UnstructuredGrid>"
                        "<Piece NumberOfPoints=\"4\" NumberOfCells=\"1\"><Points>"
                        "<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">"
                        "0 0 0 1 0 0 0 1 0 0 0 nan</DataArray></Points></Piece>"
                        "</UnstructuredGrid></VTKFile>";
  try {
    readVtu(nan);
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), nan +
                                         ": the Points' DataArray: value 12 is not a number; "
                                         "expected ascii numbers separated by spaces");
  }
  std::filesystem::remove(nan);
  // the file's attributes are quoted, never echoed: a 2 MB count, bytes that are not text
  const auto messageOf = [](const std::string& name, const std::string& dataArray) {
    const std::string file = tempPath(name);
    std::ofstream(file, std::ios::binary)
        << "<VTKFile type=\"UnstructuredGrid\"><UnstructuredGrid>"
           "<Piece NumberOfPoints=\"4\" NumberOfCells=\"1\"><Points>"
        << dataArray
        << ">0 0 0 1 0 0 0 1 0 0 0 1</DataArray></Points></Piece></UnstructuredGrid></VTKFile>";
    std::string what = "(no error)";
    try {
      readVtu(file);
    } catch (const Error& e) {
      what = e.what();
    }
    std::filesystem::remove(file);
    return what.substr(what.find(name) + name.size());
  };
  const std::string count =
      messageOf("count.vtu", "<DataArray type=\"Float64\" NumberOfComponents=\"" +
                                 std::string(2000000, 'x') + "\" format=\"ascii\"");
  EXPECT_EQ(count, ": NumberOfComponents '" + std::string(60, 'x') +
                       " ...' (2000000 characters) is not a whole number in [0, 1048576]");
  EXPECT_EQ(messageOf("format.vtu",
                      "<DataArray Name=\"p\x01\" type=\"Float64\" NumberOfComponents=\"3\" "
                      "format=\"asc\x85\""),
            ": DataArray 'p\\x01': format 'asc\\x85' is not supported; expected 'binary' or "
            "'ascii'");
  SlabSpec s;
  s.targetNodes = 50;
  const TetMesh m = makeSlab(s);
  EXPECT_THROW(writeVtu(tempPath("short.vtu"), m, {{"t", 1, {1.0, 2.0}}}, {}), Error);
  EXPECT_FALSE(std::filesystem::exists(tempPath("short.vtu")));
}

}  // namespace
}  // namespace esim
