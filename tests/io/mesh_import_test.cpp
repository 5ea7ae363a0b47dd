// mesh_import_test.cpp - surface reading, surface checks and Mesh_3 tetrahedralization.
//
// Surfaces are written inline to a per-test temp dir (cube OBJ/STL/PLY, broken
// variants); the liver asset is meshed with coarse sizes to keep the binary fast.
#include "sim/io/mesh_import.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <map>

#include "sim/core_error.h"

namespace esim {
namespace {

namespace fs = std::filesystem;

const std::string kLiver = std::string(ESIM_SOURCE_DIR) + "/assets/liver.obj";

// ---- helpers ----
fs::path tempDir() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  fs::path dir = fs::temp_directory_path() / (std::string("esim_mesh_import_") + info->name() +
                                              "_" + std::to_string(static_cast<long>(::getpid())));
  fs::create_directories(dir);
  return dir;
}

// axis-aligned box [lo, hi], 12 triangles counter-clockwise seen from outside
SurfaceMesh makeBox(const Vec3& lo, const Vec3& hi) {
  SurfaceMesh s;
  for (int i = 0; i < 8; ++i) {
    s.vertices.emplace_back(i & 1 ? hi.x() : lo.x(), i & 2 ? hi.y() : lo.y(),
                            i & 4 ? hi.z() : lo.z());
  }
  // quads (outward), split along their first diagonal
  const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                           {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads) {
    s.triangles.push_back({q[0], q[1], q[2]});
    s.triangles.push_back({q[0], q[2], q[3]});
  }
  return s;
}

SurfaceMesh merge(const SurfaceMesh& a, const SurfaceMesh& b) {
  SurfaceMesh s = a;
  const int off = static_cast<int>(a.vertices.size());
  s.vertices.insert(s.vertices.end(), b.vertices.begin(), b.vertices.end());
  for (Tri t : b.triangles) s.triangles.push_back({t[0] + off, t[1] + off, t[2] + off});
  return s;
}

std::string writeObj(const fs::path& path, const SurfaceMesh& s) {
  std::ofstream out(path);
  out.precision(17);
  for (const Vec3& p : s.vertices) out << "v " << p.x() << " " << p.y() << " " << p.z() << "\n";
  for (const Tri& t : s.triangles)
    out << "f " << t[0] + 1 << " " << t[1] + 1 << " " << t[2] + 1 << "\n";
  return path.string();
}

std::string writeStl(const fs::path& path, const SurfaceMesh& s) {
  std::ofstream out(path);
  out.precision(17);
  out << "solid box\n";
  for (const Tri& t : s.triangles) {
    const Vec3 n = (s.vertices[t[1]] - s.vertices[t[0]])
                       .cross(s.vertices[t[2]] - s.vertices[t[0]])
                       .normalized();
    out << "facet normal " << n.x() << " " << n.y() << " " << n.z() << "\nouter loop\n";
    for (int v : t) {
      const Vec3& p = s.vertices[v];
      out << "vertex " << p.x() << " " << p.y() << " " << p.z() << "\n";
    }
    out << "endloop\nendfacet\n";
  }
  out << "endsolid box\n";
  return path.string();
}

std::string writePly(const fs::path& path, const SurfaceMesh& s) {
  std::ofstream out(path);
  out.precision(17);
  out << "ply\nformat ascii 1.0\nelement vertex " << s.vertices.size()
      << "\nproperty float x\nproperty float y\nproperty float z\nelement face "
      << s.triangles.size() << "\nproperty list uchar int vertex_indices\nend_header\n";
  for (const Vec3& p : s.vertices) out << p.x() << " " << p.y() << " " << p.z() << "\n";
  for (const Tri& t : s.triangles) out << "3 " << t[0] << " " << t[1] << " " << t[2] << "\n";
  return path.string();
}

std::string base64(const std::vector<unsigned char>& bytes) {
  static const char* abc = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  for (size_t i = 0; i < bytes.size(); i += 3) {
    const unsigned n = bytes[i] << 16 | (i + 1 < bytes.size() ? bytes[i + 1] << 8 : 0) |
                       (i + 2 < bytes.size() ? bytes[i + 2] : 0);
    out += abc[n >> 18 & 63];
    out += abc[n >> 12 & 63];
    out += i + 1 < bytes.size() ? abc[n >> 6 & 63] : '=';
    out += i + 2 < bytes.size() ? abc[n & 63] : '=';
  }
  return out;
}

// glTF 2.0 with an embedded buffer (float positions, uint16 indices) and a node
// translation, which readSurface must apply
std::string writeGltf(const fs::path& path, const SurfaceMesh& s, const Vec3& translation) {
  std::vector<unsigned char> bytes;
  auto append = [&](const void* p, size_t n) {
    bytes.insert(bytes.end(), static_cast<const unsigned char*>(p),
                 static_cast<const unsigned char*>(p) + n);
  };
  Eigen::Vector3f lo = s.vertices[0].cast<float>(), hi = lo;
  for (const Vec3& v : s.vertices) {
    const Eigen::Vector3f f = v.cast<float>();
    append(f.data(), 12);
    lo = lo.cwiseMin(f), hi = hi.cwiseMax(f);
  }
  const size_t positionBytes = bytes.size();
  for (const Tri& t : s.triangles)
    for (int v : t) {
      const auto i = static_cast<std::uint16_t>(v);
      append(&i, 2);
    }
  std::ofstream out(path);
  out.precision(17);
  out << R"({"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],)"
      << R"("nodes":[{"mesh":0,"translation":[)" << translation.x() << "," << translation.y() << ","
      << translation.z() << "]}],"
      << R"("meshes":[{"primitives":[{"attributes":{"POSITION":0},"indices":1,"mode":4}]}],)"
      << R"("buffers":[{"byteLength":)" << bytes.size()
      << R"(,"uri":"data:application/octet-stream;base64,)" << base64(bytes) << R"("}],)"
      << R"("bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":)" << positionBytes
      << R"(,"target":34962},{"buffer":0,"byteOffset":)" << positionBytes << R"(,"byteLength":)"
      << bytes.size() - positionBytes << R"(,"target":34963}],)"
      << R"("accessors":[{"bufferView":0,"componentType":5126,"count":)" << s.vertices.size()
      << R"(,"type":"VEC3","min":[)" << lo.x() << "," << lo.y() << "," << lo.z() << R"(],"max":[)"
      << hi.x() << "," << hi.y() << "," << hi.z() << "]},"
      << R"({"bufferView":1,"componentType":5123,"count":)" << 3 * s.triangles.size()
      << R"(,"type":"SCALAR"}]})";
  return path.string();
}

// message of the esim::Error thrown by f ("" if none)
template <class F>
std::string errorOf(F&& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

MeshingOptions coarse(double cellSizeM) {
  MeshingOptions o;
  o.cellSizeM = cellSizeM;
  return o;
}

// every boundary edge in exactly two boundary faces, in opposite directions
void expectWatertight(const TetMesh& mesh) {
  std::map<std::pair<int, int>, int> directed;
  const auto faces = boundaryFaces(mesh);
  ASSERT_FALSE(faces.empty());
  for (const auto& f : faces) {
    for (int k = 0; k < 3; ++k) ++directed[{f.nodes[k], f.nodes[(k + 1) % 3]}];
  }
  int bad = 0;
  for (const auto& [edge, count] : directed) {
    auto rev = directed.find({edge.second, edge.first});
    if (count != 1 || rev == directed.end() || rev->second != 1) ++bad;
  }
  EXPECT_EQ(bad, 0) << "boundary edges not shared by exactly two oppositely oriented faces";
  // divergence theorem over the boundary faces equals the sum of tet volumes
  double sixV = 0;
  for (const auto& f : faces) {
    sixV += mesh.nodes[f.nodes[0]].dot(mesh.nodes[f.nodes[1]].cross(mesh.nodes[f.nodes[2]]));
  }
  EXPECT_NEAR(sixV / 6.0, meshVolume(mesh), 1e-9 * meshVolume(mesh));
}

void expectValidPositive(const TetMesh& mesh, const std::string& name) {
  EXPECT_NO_THROW(validateMesh(mesh, name));
  for (int e = 0; e < mesh.numTets(); ++e) ASSERT_GT(tetVolume(mesh, e), 0.0) << "tet " << e;
  // every node is used by a tet
  std::vector<int> used(mesh.numNodes(), 0);
  for (const Tet& t : mesh.tets)
    for (int v : t) used[v] = 1;
  EXPECT_EQ(std::count(used.begin(), used.end(), 0), 0);
}

// ---- the liver asset ----
TEST(MeshImport, LiverAssetIsAClosedOrganSizedSurface) {
  const SurfaceMesh s = readSurface(kLiver);
  EXPECT_GE(s.triangles.size(), 5000u);
  EXPECT_LE(s.triangles.size(), 10000u);
  EXPECT_NO_THROW(checkSurface(s, kLiver));
  Vec3 lo = s.vertices[0], hi = s.vertices[0];
  for (const Vec3& p : s.vertices) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  const Vec3 size = hi - lo;
  EXPECT_NEAR(size.x(), 0.160, 1e-6);
  EXPECT_NEAR(size.y(), 0.100, 1e-6);
  EXPECT_NEAR(size.z(), 0.070, 1e-6);
  EXPECT_GT(enclosedVolume(s), 0.0) << "asset must be oriented outward";
}

TEST(MeshImport, LiverTetrahedralizesWatertightWithinTwoPercentVolume) {
  const double surfaceVolume = enclosedVolume(readSurface(kLiver));
  const TetMesh mesh = loadTetMesh(kLiver, coarse(0.008));
  expectValidPositive(mesh, "liver");
  expectWatertight(mesh);
  EXPECT_GT(mesh.numNodes(), 500);
  EXPECT_NEAR(meshVolume(mesh), surfaceVolume, 0.02 * surfaceVolume);
  const MeshQuality q = meshQuality(mesh);
  EXPECT_GE(q.minDihedralDeg, 5.0);  // sliver perturbation/exudation worked
  EXPECT_EQ(mesh.nodeSets.at("boundary"), boundaryNodes(mesh, boundaryFaces(mesh)));
}

TEST(MeshImport, MeshingIsDeterministic) {
  const SurfaceMesh s = readSurface(kLiver);
  const TetMesh a = tetrahedralize(s, coarse(0.010), "liver");
  const TetMesh b = tetrahedralize(s, coarse(0.010), "liver");
  ASSERT_EQ(a.numNodes(), b.numNodes());
  ASSERT_EQ(a.numTets(), b.numTets());
  for (int i = 0; i < a.numNodes(); ++i) ASSERT_EQ(a.nodes[i], b.nodes[i]) << "node " << i;
  EXPECT_EQ(a.tets, b.tets);
}

// ---- refinement around a planned cut ----
// the liver's top along y = 0 (z ~ 15-21 mm there), meshed at 10 mm, 3 mm near the cut
MeshingOptions refinedAlongTop() {
  MeshingOptions o = coarse(0.010);
  o.refinement.enabled = true;
  o.refinement.fromM = Vec3(-0.04, 0, 0.018);
  o.refinement.toM = Vec3(0.04, 0, 0.018);
  o.refinement.cellSizeM = 0.003;
  o.refinement.widthM = 0.008;
  return o;
}

double distanceToSegment(const Vec3& p, const Vec3& a, const Vec3& b) {
  const double s = std::clamp((p - a).dot(b - a) / (b - a).squaredNorm(), 0.0, 1.0);
  return (p - (a + s * (b - a))).norm();
}

// mean edge length of the tets (or boundary faces) whose centroid lies within `near` of
// the segment, and of those farther than `far`
struct EdgeStats {
  double nearMeanM = 0, farMeanM = 0;
  int nearCount = 0, farCount = 0;
};

template <class Cells>
EdgeStats edgeStats(const TetMesh& mesh, const Cells& cells, const MeshingOptions& o, double near,
                    double far) {
  EdgeStats st;
  for (const auto& cell : cells) {
    const int n = static_cast<int>(cell.size());
    Vec3 c = Vec3::Zero();
    double sum = 0;
    int edges = 0;
    for (int i = 0; i < n; ++i) {
      c += mesh.nodes[cell[i]] / n;
      for (int j = i + 1; j < n; ++j, ++edges)
        sum += (mesh.nodes[cell[i]] - mesh.nodes[cell[j]]).norm();
    }
    const double d = distanceToSegment(c, o.refinement.fromM, o.refinement.toM);
    if (d <= near) st.nearMeanM += sum / edges, ++st.nearCount;
    if (d > far) st.farMeanM += sum / edges, ++st.farCount;
  }
  if (st.nearCount > 0) st.nearMeanM /= st.nearCount;
  if (st.farCount > 0) st.farMeanM /= st.farCount;
  return st;
}

TEST(MeshImport, RefinementMakesTetsAndFacetsFinerNearTheCut) {
  const SurfaceMesh s = readSurface(kLiver);
  const double surfaceVolume = enclosedVolume(s);
  const MeshingOptions o = refinedAlongTop();
  const TetMesh plain = tetrahedralize(s, coarse(0.010), "liver");
  const TetMesh mesh = tetrahedralize(s, o, "liver");
  expectValidPositive(mesh, "liver refined");
  expectWatertight(mesh);
  EXPECT_NEAR(meshVolume(mesh), surfaceVolume, 0.02 * surfaceVolume);
  EXPECT_GE(meshQuality(mesh).minDihedralDeg, 5.0);
  EXPECT_GT(mesh.numNodes(), plain.numNodes() + 300);
  // tets: within width of the segment vs beyond twice the width (the global size)
  const double w = o.refinement.widthM;
  const EdgeStats tets = edgeStats(mesh, mesh.tets, o, w, 2 * w);
  ASSERT_GE(tets.nearCount, 100);
  ASSERT_GE(tets.farCount, 100);
  EXPECT_LT(tets.nearMeanM, 0.5 * tets.farMeanM)
      << "near " << tets.nearMeanM << " m, far " << tets.farMeanM << " m";
  RecordProperty("tet_edge_near_over_far", std::to_string(tets.nearMeanM / tets.farMeanM));
  // the unrefined mesh has no such contrast (the test measures the sizing field)
  const EdgeStats plainTets = edgeStats(plain, plain.tets, o, w, 2 * w);
  EXPECT_GT(plainTets.nearMeanM, 0.7 * plainTets.farMeanM);
  // surface facets follow the same field: near the cut they are at least 2x smaller than
  // without refinement (far facets are bounded by curvature, so compare near with near)
  auto faceList = [](const TetMesh& m) {
    std::vector<std::array<int, 3>> faces;
    for (const auto& f : boundaryFaces(m)) faces.push_back(f.nodes);
    return faces;
  };
  const EdgeStats facets = edgeStats(mesh, faceList(mesh), o, w, 2 * w);
  const EdgeStats plainFacets = edgeStats(plain, faceList(plain), o, w, 2 * w);
  ASSERT_GE(facets.nearCount, 20);
  ASSERT_GE(plainFacets.nearCount, 5);
  EXPECT_LT(facets.nearMeanM, 0.5 * plainFacets.nearMeanM)
      << "refined " << facets.nearMeanM << " m, plain " << plainFacets.nearMeanM << " m";
  RecordProperty("facet_edge_near_refined_over_plain",
                 std::to_string(facets.nearMeanM / plainFacets.nearMeanM));
  RecordProperty("nodes_plain_refined",
                 std::to_string(plain.numNodes()) + " " + std::to_string(mesh.numNodes()));
}

TEST(MeshImport, RefinedMeshingIsDeterministic) {
  const SurfaceMesh s = readSurface(kLiver);
  const TetMesh a = tetrahedralize(s, refinedAlongTop(), "liver");
  const TetMesh b = tetrahedralize(s, refinedAlongTop(), "liver");
  ASSERT_EQ(a.numNodes(), b.numNodes());
  ASSERT_EQ(a.numTets(), b.numTets());
  for (int i = 0; i < a.numNodes(); ++i) ASSERT_EQ(a.nodes[i], b.nodes[i]) << "node " << i;
  EXPECT_EQ(a.tets, b.tets);
}

TEST(MeshImport, BadRefinementOptionsAreReported) {
  const SurfaceMesh box = makeBox({0, 0, 0}, {0.02, 0.02, 0.02});
  MeshingOptions o = coarse(0.004);
  o.refinement.enabled = true;
  o.refinement.fromM = Vec3(0, 0.01, 0.02);
  o.refinement.toM = Vec3(0.02, 0.01, 0.02);
  auto errorWith = [&](auto change) {
    MeshingOptions bad = o;
    change(bad.refinement);
    return errorOf([&] { tetrahedralize(box, bad, "box.obj"); });
  };
  using R = MeshingOptions::Refinement;
  EXPECT_EQ(errorWith([](R& r) {
              r.cellSizeM = 0;
            }).rfind("box.obj: refinement cell size must be > 0 m and <= the cell size 0.004", 0),
            0u);
  EXPECT_EQ(errorWith([](R& r) {
              r.cellSizeM = 0.005;
            }).rfind("box.obj: refinement cell size must be > 0 m and <= the cell size", 0),
            0u);
  EXPECT_EQ(
      errorWith([](R& r) { r.widthM = -1; }).rfind("box.obj: refinement width must be > 0 m", 0),
      0u);
  EXPECT_EQ(errorWith([](R& r) { r.toM = r.fromM; })
                .rfind("box.obj: refinement segment needs two distinct finite ends (from (0, "
                       "0.01, 0.02) to (0, 0.01, 0.02) m)",
                       0),
            0u);
  // disabled refinement ignores its fields
  EXPECT_EQ(errorWith([](R& r) { r.enabled = false, r.cellSizeM = 0; }), "");
  // the size guard counts the fine zone: 0.02 mm cells along the cube
  const std::string msg = errorWith([](R& r) { r.cellSizeM = 2e-5; });
  EXPECT_NE(msg.find("would give about"), std::string::npos) << msg;
}

TEST(MeshImport, ElectrodeAssetsAreClosedWithTipAtOriginAlongZ) {
  for (const char* name : {"electrode_blade.obj", "electrode_needle.obj"}) {
    const std::string path = std::string(ESIM_SOURCE_DIR) + "/assets/" + name;
    SCOPED_TRACE(path);
    const SurfaceMesh s = readSurface(path);
    EXPECT_NO_THROW(checkSurface(s, path));
    EXPECT_GT(enclosedVolume(s), 0.0);
    Vec3 lo = s.vertices[0], hi = s.vertices[0];
    for (const Vec3& p : s.vertices) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
    EXPECT_EQ(lo.z(), 0.0);  // tip at z = 0 ...
    EXPECT_NE(std::find(s.vertices.begin(), s.vertices.end(), Vec3::Zero()), s.vertices.end());
    EXPECT_NEAR(lo.x() + hi.x(), 0.0, 1e-9);  // ... on the z axis
    EXPECT_NEAR(lo.y() + hi.y(), 0.0, 1e-9);
    EXPECT_GT(hi.z(), 0.02);  // handle toward +z, metres
    EXPECT_LT(hi.z(), 0.05);
  }
}

// ---- formats: a 20 mm cube ----
TEST(MeshImport, CubeObjStlPlyGltfMeshWithinTwoPercentVolume) {
  const fs::path dir = tempDir();
  const SurfaceMesh box = makeBox({0, 0, 0}, {0.02, 0.02, 0.02});
  const double exact = 8e-6;
  for (const std::string& path : {writeObj(dir / "cube.obj", box), writeStl(dir / "cube.stl", box),
                                  writePly(dir / "cube.ply", box)}) {
    SCOPED_TRACE(path);
    const SurfaceMesh s = readSurface(path);
    EXPECT_EQ(s.vertices.size(), 8u) << "duplicate vertices must be welded";
    EXPECT_EQ(s.triangles.size(), 12u);
    EXPECT_NEAR(enclosedVolume(s), exact, 1e-12);
    const TetMesh mesh = loadTetMesh(path, coarse(0.004));
    expectValidPositive(mesh, path);
    expectWatertight(mesh);
    EXPECT_NEAR(meshVolume(mesh), exact, 0.02 * exact);
  }
  // glTF with a node translation of 0.1 m in x
  const std::string gltfPath = writeGltf(dir / "cube.gltf", box, {0.1, 0, 0});
  const SurfaceMesh moved = readSurface(gltfPath);
  ASSERT_EQ(moved.triangles.size(), 12u);
  double minX = 1e9;
  for (const Vec3& p : moved.vertices) minX = std::min(minX, p.x());
  EXPECT_NEAR(minX, 0.1, 1e-7) << "node transform applied";
  EXPECT_NEAR(meshVolume(loadTetMesh(gltfPath, coarse(0.004))), exact, 0.02 * exact);
  // millimetre file with a scale factor
  SurfaceMesh mm = box;
  for (Vec3& p : mm.vertices) p *= 1000.0;
  const std::string mmPath = writeObj(dir / "cube_mm.obj", mm);
  EXPECT_NEAR(meshVolume(loadTetMesh(mmPath, coarse(0.004), 1e-3)), exact, 0.02 * exact);
  fs::remove_all(dir);
}

TEST(MeshImport, InwardSurfaceIsFlippedOutward) {
  SurfaceMesh s = makeBox({0, 0, 0}, {0.01, 0.01, 0.01});
  for (Tri& t : s.triangles) std::swap(t[1], t[2]);
  EXPECT_NEAR(enclosedVolume(s), -1e-6, 1e-15);
  checkSurface(s, "inward");  // consistently oriented, only inward
  orientOutward(s);
  EXPECT_NEAR(enclosedVolume(s), 1e-6, 1e-15);
  const TetMesh mesh = tetrahedralize(s, coarse(0.003), "inward");
  EXPECT_NEAR(meshVolume(mesh), 1e-6, 0.02e-6);
}

// ---- bad input: one clear message naming the file and the problem ----
TEST(MeshImport, MissingFileIsReported) {
  const std::string path = "/nonexistent/dir/organ.obj";
  EXPECT_EQ(errorOf([&] { readSurface(path); }), path + ": file not found");
  EXPECT_EQ(errorOf([&] { loadTetMesh(path, coarse(0.01)); }), path + ": file not found");
}

TEST(MeshImport, GarbageFileIsReported) {
  const fs::path dir = tempDir();
  for (const char* name : {"garbage.obj", "garbage.stl", "garbage.ply"}) {
    const std::string path = (dir / name).string();
    {
      std::ofstream out(path, std::ios::binary);
      unsigned x = 12345;
      for (int i = 0; i < 3000; ++i)
        out.put(static_cast<char>((x = x * 1103515245u + 12345u) >> 24));
    }
    const std::string msg = errorOf([&] { readSurface(path); });
    EXPECT_EQ(msg.rfind(path + ": cannot read surface mesh: ", 0), 0u) << msg;
  }
  fs::remove_all(dir);
}

// assimp reads in a child process: a reader that crashes (a damaged file that corrupts its
// heap: tests/fuzz/fuzz_surface found such inputs) is an input error naming the file and the
// signal, and this process goes on (ESIM_FAULT=reader: the child raises SIGSEGV before
// reading); one that hangs is killed at its deadline; the same file read again after them
// is the cube
TEST(MeshImport, AReaderThatCrashesOrHangsIsAnInputError) {
  const fs::path dir = tempDir();
  const std::string path = writeObj(dir / "cube.obj", makeBox({0, 0, 0}, {0.01, 0.01, 0.01}));
  ASSERT_EQ(::setenv("ESIM_FAULT", "reader", 1), 0);
  const std::string msg = errorOf([&] { readSurface(path); });
  ::unsetenv("ESIM_FAULT");
  // killed by the signal; under ASan its handler reports the crash and exits with status 1
  const std::string how = msg.find("(exit status 1)") != std::string::npos
                              ? "exit status 1"
                              : "signal 11, Segmentation fault";
  EXPECT_EQ(msg, path + ": cannot read surface mesh: the reader (assimp) crashed on it (" + how +
                     "): a damaged file? expected OBJ, STL, PLY or glTF/GLB with triangles");
  // a reader that never returns (assimp 5.2 spins on some damaged files): killed at the
  // deadline, the same kind of error
  ASSERT_EQ(::setenv("ESIM_FAULT", "reader_hang", 1), 0);
  const auto t0 = std::chrono::steady_clock::now();
  const std::string hung = errorOf([&] { readSurface(path, 1.0, 0.5); });
  const double tookS = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ::unsetenv("ESIM_FAULT");
  EXPECT_EQ(hung, path +
                      ": cannot read surface mesh: the reader (assimp) did not finish within 0.5 "
                      "s: a damaged file? expected OBJ, STL, PLY or glTF/GLB with triangles");
  EXPECT_GE(tookS, 0.5);
  EXPECT_LT(tookS, 10.0);
  const SurfaceMesh cube = readSurface(path);
  EXPECT_EQ(cube.vertices.size(), 8u);
  EXPECT_EQ(cube.triangles.size(), 12u);
  EXPECT_NEAR(enclosedVolume(cube), 1e-6, 1e-12);  // assimp keeps floats
  fs::remove_all(dir);
}

// a tet mesh (the .vtu fields of esim run --fields) given as a scene's surface: said so,
// with what is expected (assimp said "No suitable reader found for the file format")
TEST(MeshImport, ATetMeshFileIsNotASurface) {
  const fs::path dir = tempDir();
  for (const char* name : {"frame_00030.vtu", "CUT.VTU"}) {
    const std::string path = (dir / name).string();
    std::ofstream(path) << "<VTKFile type=\"UnstructuredGrid\"></VTKFile>\n";
    const std::string msg = errorOf([&] { readSurface(path); });
    EXPECT_EQ(msg.rfind(path + ": a tet mesh (.vtu", 0), 0u) << msg;
    EXPECT_NE(msg.find("expected a closed surface (OBJ, STL, PLY, OFF, glTF)"), std::string::npos)
        << msg;
  }
  fs::remove_all(dir);
}

TEST(MeshImport, SurfaceWithoutTrianglesIsReported) {
  const fs::path dir = tempDir();
  const std::string path = (dir / "lines.obj").string();
  std::ofstream(path) << "v 0 0 0\nv 1 0 0\nv 0 1 0\nl 1 2 3\n";
  const std::string msg = errorOf([&] { readSurface(path); });
  EXPECT_EQ(msg.rfind(path + ": surface mesh has no triangles", 0), 0u) << msg;
  fs::remove_all(dir);
}

TEST(MeshImport, OpenSurfaceIsReported) {
  const fs::path dir = tempDir();
  SurfaceMesh s = makeBox({0, 0, 0}, {0.01, 0.01, 0.01});
  s.triangles.resize(10);  // drop the last quad (x = 0.01 face)
  const std::string path = writeObj(dir / "open_cube.obj", s);
  const std::string msg = errorOf([&] { loadTetMesh(path, coarse(0.004)); });
  EXPECT_EQ(msg.rfind(path + ": surface is not closed: 4 boundary edges", 0), 0u) << msg;
  EXPECT_NE(msg.find("e.g. the edge from (0.01, "), std::string::npos) << msg;
  fs::remove_all(dir);
}

TEST(MeshImport, SelfIntersectingSurfaceIsReported) {
  const fs::path dir = tempDir();
  const SurfaceMesh s = merge(makeBox({0, 0, 0}, {0.01, 0.01, 0.01}),
                              makeBox({0.005, 0.004, 0.003}, {0.015, 0.014, 0.013}));
  const std::string path = writeObj(dir / "two_cubes.obj", s);
  const std::string msg = errorOf([&] { loadTetMesh(path, coarse(0.004)); });
  EXPECT_EQ(msg.rfind(path + ": surface self-intersects (", 0), 0u) << msg;
  EXPECT_NE(msg.find("pairs of faces), e.g. faces "), std::string::npos) << msg;
  fs::remove_all(dir);
}

TEST(MeshImport, InconsistentOrientationIsReported) {
  SurfaceMesh s = makeBox({0, 0, 0}, {0.01, 0.01, 0.01});
  std::swap(s.triangles[3][1], s.triangles[3][2]);
  const std::string msg = errorOf([&] { checkSurface(s, "flipped.obj"); });
  EXPECT_EQ(msg.rfind("flipped.obj: surface orientation is inconsistent: 3 edges", 0), 0u) << msg;
}

TEST(MeshImport, NonManifoldEdgeIsReported) {
  // two cubes touching along one edge: that edge is in four triangles
  const fs::path dir = tempDir();
  const SurfaceMesh s =
      merge(makeBox({0, 0, 0}, {0.01, 0.01, 0.01}), makeBox({0.01, 0.01, 0}, {0.02, 0.02, 0.01}));
  const std::string path = writeObj(dir / "edge_cubes.obj", s);
  const std::string msg = errorOf([&] { loadTetMesh(path, coarse(0.004)); });
  EXPECT_EQ(msg.rfind(path + ": surface is non-manifold: 1 edges shared by more than two", 0), 0u)
      << msg;
  fs::remove_all(dir);
}

TEST(MeshImport, NonManifoldVertexIsReported) {
  // two cubes touching at one corner (welded by position when read)
  const fs::path dir = tempDir();
  const SurfaceMesh s = merge(makeBox({0, 0, 0}, {0.01, 0.01, 0.01}),
                              makeBox({0.01, 0.01, 0.01}, {0.02, 0.02, 0.02}));
  const std::string path = writeObj(dir / "corner_cubes.obj", s);
  EXPECT_EQ(readSurface(path).vertices.size(), 15u);
  const std::string msg = errorOf([&] { loadTetMesh(path, coarse(0.004)); });
  EXPECT_EQ(msg.rfind(path + ": surface is non-manifold at vertex (0.01, 0.01, 0.01)", 0), 0u)
      << msg;
  fs::remove_all(dir);
}

TEST(MeshImport, BadOptionsAndUnitMixUpAreReported) {
  const SurfaceMesh box = makeBox({0, 0, 0}, {0.02, 0.02, 0.02});
  EXPECT_EQ(errorOf([&] {
              tetrahedralize(box, coarse(0), "box.obj");
            }).rfind("box.obj: cell size must be > 0 m", 0),
            0u);
  MeshingOptions badAngle = coarse(0.004);
  badAngle.facetAngleDeg = 40;
  EXPECT_EQ(errorOf([&] {
              tetrahedralize(box, badAngle, "box.obj");
            }).rfind("box.obj: facet angle must be in (0, 30]", 0),
            0u);
  // a 20 m box meshed at 1 mm: millimetres read as metres
  SurfaceMesh big = box;
  for (Vec3& p : big.vertices) p *= 1000.0;
  const std::string msg = errorOf([&] { tetrahedralize(big, coarse(0.001), "big.obj"); });
  EXPECT_NE(msg.find("big.obj: cell size 0.001 m would give about"), std::string::npos) << msg;
  EXPECT_NE(msg.find("check the units"), std::string::npos) << msg;
}

}  // namespace
}  // namespace esim
