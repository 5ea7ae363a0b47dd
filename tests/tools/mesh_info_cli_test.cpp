// mesh_info_cli_test.cpp - `esim mesh-info` end to end on the slab and a .vtu it wrote: the
// counts it prints, and the options a mode would silently ignore refused with exit 2 (a
// surface file beside --slab-nodes, meshing options for the slab or a .vtu).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "tests/scratch_dir_util.h"
#include "tests/tools/cli_test_util.h"

namespace {

using esim::cli_test::shell;

class MeshInfoCli : public esim::test::ScratchDirTest {
 protected:
  static std::string esim(const std::string& args) {
    return std::string("\"") + ESIM_EXE + "\" mesh-info " + args;
  }
};

TEST_F(MeshInfoCli, TheSlabAndTheVtuItWroteHaveTheSameCounts) {
  const std::string vtu = (root_ / "slab.vtu").string();
  const auto slab = shell(esim("--slab-nodes 300 --vtu \"" + vtu + "\""));
  ASSERT_EQ(slab.exitCode, 0) << slab.output;
  EXPECT_NE(slab.output.find("nodes          300\n"), std::string::npos) << slab.output;
  const auto read = shell(esim("\"" + vtu + "\""));
  ASSERT_EQ(read.exitCode, 0) << read.output;
  EXPECT_NE(read.output.find("nodes          300\n"), std::string::npos) << read.output;
}

// a cut's fields: two unit-corner tets sharing a face, and a third hanging by an edge of
// them: two pieces through shared faces, the loose one named
TEST_F(MeshInfoCli, ThePiecesACutLeftLooseAreCounted) {
  const std::string vtu = (root_ / "loose.vtu").string();
  std::ofstream(vtu)
      << "<VTKFile type=\"UnstructuredGrid\"><UnstructuredGrid>"
         "<Piece NumberOfPoints=\"7\" NumberOfCells=\"3\"><Points>"
         "<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">"
         "0 0 0 1 0 0 0 1 0 0 0 1 1 1 1 0 -1 0 0 0 -1</DataArray></Points><Cells>"
         "<DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">"
         "0 1 2 3 1 2 3 4 0 1 5 6</DataArray>"
         "<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">4 8 12</DataArray>"
         "<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">10 10 10</DataArray>"
         "</Cells></Piece></UnstructuredGrid></VTKFile>";
  const auto r = shell(esim("\"" + vtu + "\""));
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_NE(r.output.find("  pieces         2 through shared faces (the largest 2 tets; the 1 "
                          "others 1 tets, "),
            std::string::npos)
      << r.output;
  const auto slab = shell(esim("--slab-nodes 300"));
  EXPECT_NE(slab.output.find("  pieces         1 through shared faces\n"), std::string::npos)
      << slab.output;
}

TEST_F(MeshInfoCli, AnOptionTheModeWouldIgnoreIsRefused) {
  const std::string vtu = (root_ / "slab.vtu").string();
  ASSERT_EQ(shell(esim("--slab-nodes 300 --vtu \"" + vtu + "\"")).exitCode, 0);
  struct Case {
    std::string args, message;
  };
  const Case cases[] = {
      {"assets/liver.obj --slab-nodes 500",
       "mesh-info: --slab-nodes reports the slab; give it without 'assets/liver.obj'"},
      {"--slab-nodes 500 --lloyd",
       "mesh-info: --lloyd is an option of meshing a surface file, and the slab is built"},
      {"slab --cell-size 0.002", "mesh-info: --cell-size is an option of meshing a surface file"},
      // a slab past the scene's tet bound (it built 1e8 nodes for minutes)
      {"--slab-nodes 100000000",
       "mesh-info: --slab-nodes 100000000 gives a grid of 1000 x 1000 x 100 nodes, 592812594 "
       "tetrahedra; at most 20000000"},
      {"\"" + vtu + "\" --refine-size 0.001",
       "--refine-size is an option of meshing a surface file, and a .vtu tet mesh is read as it "
       "is"},
      // the refinement's own options without its segment were ignored (nan meshed)
      {"assets/liver.obj --refine-size nan",
       "mesh-info: --refine-size is an option of the refinement around a planned cut, which "
       "needs --refine-from and --refine-to"},
      // --vtu checked before the meshing (it failed after it: "cannot rename temporary file:
      // Is a directory", "cannot open for writing")
      {"assets/liver.obj --vtu \"" + root_.string() + "/mesh.txt\"",
       "mesh-info: --vtu '" + root_.string() + "/mesh.txt' must end in .vtu"},
      {"assets/liver.obj --vtu \"" + root_.string() + "/d.vtu\"", "d.vtu' is a folder"},
      {"assets/liver.obj --vtu \"" + root_.string() + "/none/x.vtu\"",
       "/none/x.vtu': the folder '" + root_.string() + "/none' does not exist"},
  };
  std::filesystem::create_directories(root_ / "d.vtu");
  for (const Case& c : cases) {
    const auto r = shell(esim(c.args));
    EXPECT_EQ(r.exitCode, 2) << c.args << "\n" << r.output;
    EXPECT_NE(r.output.find(c.message), std::string::npos) << c.args << "\n" << r.output;
  }
}

}  // namespace
