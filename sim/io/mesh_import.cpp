// mesh_import.cpp - assimp surface reading, surface checks, Mesh_3 front end.
//
// 1. readSurface: assimp -> concatenated triangles, vertices welded by exact position
//    (a PLY header is checked first: assimp hangs on one without end_header). assimp runs
//    in a child process (fork), which sends the triangles back through a pipe: a damaged
//    file that makes assimp corrupt its heap or abort (found by tests/fuzz/fuzz_surface:
//    ASan "CHECK failed" in assimp's delete after garbage OBJ and PLY input, never
//    reproduced by one input alone) kills the child, and the run gets an input error naming
//    the file and the signal instead of a crash or a corrupted heap.
// 2. checkSurface: topology checks in plain C++ (sorted edge lists), then the CGAL
//    self-intersection test (mesh_cgal.cpp).
// 3. tetrahedralize: option checks and a size guard, Mesh_3, validateMesh.
#include "sim/io/mesh_import.h"

#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <fcntl.h>
#include <poll.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <assimp/Importer.hpp>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <new>
#include <numbers>
#include <sstream>

#include "sim/core_error.h"
#include "sim/io/mesh_cgal.h"
#include "sim/message_text.h"

namespace esim {
namespace {

std::string formatPoint(const Vec3& p) {
  std::ostringstream s;
  s.precision(6);
  s << "(" << p.x() << ", " << p.y() << ", " << p.z() << ")";
  return s.str();
}

std::string formatEdge(const SurfaceMesh& surface, int a, int b) {
  return "the edge from " + formatPoint(surface.vertices[a]) + " to " +
         formatPoint(surface.vertices[b]) + " m";
}

// one directed use of an undirected edge (lo < hi) by a triangle
struct EdgeUse {
  int lo, hi;
  bool forward;  // the triangle runs lo -> hi
  int triangle;
  bool operator<(const EdgeUse& o) const {
    return std::tie(lo, hi, triangle) < std::tie(o.lo, o.hi, o.triangle);
  }
};

// assimp 5.2 (Debian 12) never returns from a PLY whose header has no end_header line (it
// spins at the end of the file: tests/fuzz/fuzz_surface/timeout-assimp-ply-no-end-header):
// a PLY file (by extension or by its "ply" magic) must have one before assimp sees it
void checkPlyHeader(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::string line;
  if (!std::getline(in, line)) return;  // empty: assimp says what is wrong
  auto trimmed = [](const std::string& text) {
    const size_t a = text.find_first_not_of(" \t\r");
    return a == std::string::npos ? std::string()
                                  : text.substr(a, text.find_last_not_of(" \t\r") - a + 1);
  };
  std::string extension = std::filesystem::path(path).extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (extension != ".ply" && line.rfind("ply", 0) != 0) return;
  while (std::getline(in, line))
    if (trimmed(line) == "end_header") return;
  throw Error(path +
              ": cannot read surface mesh: the PLY header has no end_header line (truncated or "
              "damaged file?)");
}

}  // namespace

// ---- reading ----
namespace {

// the answer's bytes are the vectors' own: both ends are this binary
static_assert(sizeof(Vec3) == 3 * sizeof(double) && sizeof(Tri) == 3 * sizeof(int));

// assimp's part of readSurface (in the child process)
SurfaceMesh importSurface(const std::string& path, double scaleToMetres) {
  // import only, then our checks, then the post-processing: assimp's loaders can hand on
  // faces of 0 indices, indices past the vertices and primitive-type flags that disagree
  // with the faces, and its Triangulate step aborts the process on the latter
  // (tests/fuzz/fuzz_surface/crash-assimp-ply-triangulate-abort)
  Assimp::Importer importer;
  const aiScene* scene = importer.ReadFile(path, aiProcess_ValidateDataStructure);
  ESIM_VERIFY(scene != nullptr, path + ": cannot read surface mesh: " +
                                    printableInMessage(importer.GetErrorString()));
  ESIM_VERIFY(!(scene->mFlags & AI_SCENE_FLAGS_INCOMPLETE) && scene->mNumMeshes > 0,
              path +
                  ": cannot read surface mesh: the file holds no mesh (unsupported or "
                  "damaged file?); expected OBJ, STL, PLY or glTF/GLB with triangles");
  for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
    aiMesh* mesh = scene->mMeshes[m];
    ESIM_VERIFY(
        mesh != nullptr && mesh->mVertices != nullptr,
        path + ": cannot read surface mesh: mesh " + std::to_string(m) + " has no vertices");
    unsigned types = 0;
    for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
      const aiFace& face = mesh->mFaces[f];
      ESIM_VERIFY(face.mNumIndices > 0, path + ": cannot read surface mesh: face " +
                                            std::to_string(f) + " of mesh " + std::to_string(m) +
                                            " has no vertices");
      for (unsigned k = 0; k < face.mNumIndices; ++k)
        ESIM_VERIFY(face.mIndices[k] < mesh->mNumVertices,
                    path + ": cannot read surface mesh: face " + std::to_string(f) + " of mesh " +
                        std::to_string(m) + " refers to vertex " +
                        std::to_string(face.mIndices[k]) + " of " +
                        std::to_string(mesh->mNumVertices));
      types |= face.mNumIndices == 1   ? aiPrimitiveType_POINT
               : face.mNumIndices == 2 ? aiPrimitiveType_LINE
               : face.mNumIndices == 3 ? aiPrimitiveType_TRIANGLE
                                       : aiPrimitiveType_POLYGON;
    }
    mesh->mPrimitiveTypes = types;  // what the faces are, whatever the loader said
  }
  scene = importer.ApplyPostProcessing(aiProcess_Triangulate | aiProcess_JoinIdenticalVertices |
                                       aiProcess_PreTransformVertices | aiProcess_SortByPType);
  ESIM_VERIFY(scene != nullptr, path + ": cannot read surface mesh: " +
                                    printableInMessage(importer.GetErrorString()));

  // concatenate all meshes; weld equal positions (STL and split OBJ groups repeat them)
  SurfaceMesh surface;
  std::map<std::array<double, 3>, int> idOfPosition;
  for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
    const aiMesh* mesh = scene->mMeshes[m];
    std::vector<int> ids(mesh->mNumVertices);
    for (unsigned v = 0; v < mesh->mNumVertices; ++v) {
      const aiVector3D& p = mesh->mVertices[v];
      const std::array<double, 3> key{p.x * scaleToMetres, p.y * scaleToMetres,
                                      p.z * scaleToMetres};
      ESIM_VERIFY(std::isfinite(key[0]) && std::isfinite(key[1]) && std::isfinite(key[2]),
                  path + ": vertex " + std::to_string(v) + " of mesh " + std::to_string(m) +
                      " has a non-finite coordinate");
      auto [it, inserted] = idOfPosition.emplace(key, static_cast<int>(surface.vertices.size()));
      if (inserted) surface.vertices.emplace_back(key[0], key[1], key[2]);
      ids[v] = it->second;
    }
    for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
      const aiFace& face = mesh->mFaces[f];
      if (face.mNumIndices != 3) continue;  // points and lines are not surface
      for (unsigned k = 0; k < 3; ++k)
        ESIM_VERIFY(face.mIndices[k] < mesh->mNumVertices,
                    path + ": cannot read surface mesh: triangle " + std::to_string(f) +
                        " of mesh " + std::to_string(m) + " refers to a missing vertex");
      surface.triangles.push_back(
          {ids[face.mIndices[0]], ids[face.mIndices[1]], ids[face.mIndices[2]]});
    }
  }
  ESIM_VERIFY(!surface.triangles.empty(),
              path + ": surface mesh has no triangles (" + std::to_string(scene->mNumMeshes) +
                  " meshes of points or lines only); expected a closed triangulated surface");
  return surface;
}

// the child's answer on the pipe: one byte, then
//   'S': int64 vertex count, int64 triangle count, the vertices' and the triangles' bytes
//        (3 doubles, 3 ints each: the vectors' own layout);
//   'E': the message of the input error (esim::Error) it threw;  'M': out of memory;
//   'X': the message of any other exception (an internal error)
bool writeAll(int fd, const void* data, size_t size) {
  const char* p = static_cast<const char*>(data);
  while (size > 0) {
    const ssize_t n = ::write(fd, p, size);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    p += n;
    size -= static_cast<size_t>(n);
  }
  return true;
}

[[noreturn]] void childReads(int fd, const std::string& path, double scaleToMetres) {
  if (const char* fault = std::getenv("ESIM_FAULT")) {  // tests: a reader that crashes, hangs
    if (std::strcmp(fault, "reader") == 0) std::raise(SIGSEGV);
    if (std::strcmp(fault, "reader_hang") == 0)
      for (;;) ::pause();
  }
  std::string reply;
  try {
    const SurfaceMesh surface = importSurface(path, scaleToMetres);
    const std::int64_t counts[2] = {static_cast<std::int64_t>(surface.vertices.size()),
                                    static_cast<std::int64_t>(surface.triangles.size())};
    const bool ok = writeAll(fd, "S", 1) && writeAll(fd, counts, sizeof counts) &&
                    writeAll(fd, surface.vertices.data(), surface.vertices.size() * sizeof(Vec3)) &&
                    writeAll(fd, surface.triangles.data(), surface.triangles.size() * sizeof(Tri));
    ::_exit(ok ? 0 : 3);
  } catch (const Error& e) {
    reply = std::string("E") + e.what();
  } catch (const std::bad_alloc&) {
    reply = "M";
  } catch (const std::exception& e) {
    reply = std::string("X") + printableInMessage(e.what());
  }
  ::_exit(writeAll(fd, reply.data(), reply.size()) ? 0 : 3);
}

}  // namespace

SurfaceMesh readSurface(const std::string& path, double scaleToMetres, double timeoutS) {
  namespace fs = std::filesystem;
  std::error_code ec;
  ESIM_VERIFY(fs::exists(path, ec), path + ": file not found");
  ESIM_VERIFY(fs::is_regular_file(path, ec),
              path + ": cannot read surface mesh: not a regular file");
  ESIM_VERIFY(std::isfinite(scaleToMetres) && scaleToMetres > 0,
              path + ": scale to metres must be a positive number");

  std::string ext = fs::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  ESIM_VERIFY(ext != ".vtu", path +
                                 ": a tet mesh (.vtu, e.g. the fields of esim run --fields) is "
                                 "not a surface; expected a closed surface (OBJ, STL, PLY, OFF, "
                                 "glTF), which is meshed with CGAL (esim mesh-info reads .vtu)");
  checkPlyHeader(path);

  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0)
    throw Error("readSurface: pipe: " + std::string(std::strerror(errno)), ErrorKind::Internal);
  const pid_t pid = ::fork();
  const int forkErrno = errno;
  if (pid == 0) {
    ::close(fds[0]);
    childReads(fds[1], path, scaleToMetres);
  }
  ::close(fds[1]);
  if (pid < 0) {
    ::close(fds[0]);
    if (forkErrno == ENOMEM || forkErrno == EAGAIN) throw std::bad_alloc();
    throw Error("readSurface: fork: " + std::string(std::strerror(forkErrno)), ErrorKind::Internal);
  }
  // the answer, read as it comes (the child blocks on a full pipe), up to the deadline; a stop
  // asked meanwhile (checkInterrupt, every 0.1 s) or the deadline ends the child
  int status = 0;
  const auto endChild = [&] {
    ::close(fds[0]);
    ::kill(pid, SIGKILL);
    while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
    }
  };
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeoutS);
  std::string reply;
  char buffer[1 << 16];
  for (;;) {
    try {
      checkInterrupt();
    } catch (...) {
      endChild();
      throw;
    }
    const double leftS =
        std::chrono::duration<double>(deadline - std::chrono::steady_clock::now()).count();
    if (leftS <= 0) {
      endChild();
      throw Error(path + ": cannot read surface mesh: the reader (assimp) did not finish within " +
                  messageNumber(timeoutS) +
                  " s: a damaged file? expected OBJ, STL, PLY or glTF/GLB with triangles");
    }
    pollfd pfd{fds[0], POLLIN, 0};
    const int ready = ::poll(&pfd, 1, static_cast<int>(std::min(100.0, leftS * 1e3)) + 1);
    if (ready < 0 && errno != EINTR) {
      endChild();
      throw Error("readSurface: poll: " + std::string(std::strerror(errno)), ErrorKind::Internal);
    }
    if (ready <= 0) continue;
    const ssize_t n = ::read(fds[0], buffer, sizeof buffer);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    reply.append(buffer, static_cast<size_t>(n));
  }
  ::close(fds[0]);
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  // a child killed by a signal, or one that did not end with exit status 0 after its whole
  // answer (under a sanitizer a crash is its report and exit status 1), crashed on the file
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0 || reply.empty()) {
    std::string how;
    if (WIFSIGNALED(status)) {
      const char* name = ::strsignal(WTERMSIG(status));
      how = "signal " + std::to_string(WTERMSIG(status)) + ", " + (name ? name : "?");
    } else {
      how = "exit status " + std::to_string(WEXITSTATUS(status));
    }
    throw Error(path + ": cannot read surface mesh: the reader (assimp) crashed on it (" + how +
                "): a damaged file? expected OBJ, STL, PLY or glTF/GLB with triangles");
  }
  switch (reply[0]) {
    case 'E':
      throw Error(reply.substr(1));
    case 'M':
      throw std::bad_alloc();
    case 'S':
      break;
    default:
      throw Error("readSurface: the reader process failed: " + reply.substr(1),
                  ErrorKind::Internal);
  }
  std::int64_t counts[2];
  if (reply.size() < 1 + sizeof counts)
    throw Error("readSurface: a short answer from the reader", ErrorKind::Internal);
  std::memcpy(counts, reply.data() + 1, sizeof counts);
  const size_t expected = 1 + sizeof counts + static_cast<size_t>(counts[0]) * sizeof(Vec3) +
                          static_cast<size_t>(counts[1]) * sizeof(Tri);
  if (!(counts[0] >= 0 && counts[1] >= 0 && reply.size() == expected))
    throw Error("readSurface: a damaged answer from the reader (" + std::to_string(reply.size()) +
                    " bytes)",
                ErrorKind::Internal);
  SurfaceMesh surface;
  const char* p = reply.data() + 1 + sizeof counts;
  surface.vertices.resize(static_cast<size_t>(counts[0]));
  surface.triangles.resize(static_cast<size_t>(counts[1]));
  if (!surface.vertices.empty())
    std::memcpy(surface.vertices.data()->data(), p, surface.vertices.size() * sizeof(Vec3));
  if (!surface.triangles.empty())
    std::memcpy(surface.triangles.data(), p + surface.vertices.size() * sizeof(Vec3),
                surface.triangles.size() * sizeof(Tri));
  return surface;
}

double enclosedVolume(const SurfaceMesh& surface) {
  double sixV = 0;
  for (const Tri& t : surface.triangles) {
    const Vec3& a = surface.vertices[t[0]];
    sixV += a.dot(surface.vertices[t[1]].cross(surface.vertices[t[2]]));
  }
  return sixV / 6.0;
}

// ---- checks ----
void checkSurface(const SurfaceMesh& surface, const std::string& source) {
  const int nv = static_cast<int>(surface.vertices.size());
  const int nt = static_cast<int>(surface.triangles.size());
  ESIM_VERIFY(nt > 0, source + ": surface mesh has no triangles");

  // 1. triangles: ids in range, three distinct vertices, non-zero area
  for (int t = 0; t < nt; ++t) {
    const Tri& tri = surface.triangles[t];
    for (int v : tri) {
      ESIM_VERIFY(v >= 0 && v < nv, source + ": triangle " + std::to_string(t) +
                                        " refers to vertex " + std::to_string(v) + " of " +
                                        std::to_string(nv));
    }
    const Vec3& a = surface.vertices[tri[0]];
    const double area2 = (surface.vertices[tri[1]] - a).cross(surface.vertices[tri[2]] - a).norm();
    ESIM_VERIFY(tri[0] != tri[1] && tri[1] != tri[2] && tri[0] != tri[2] && area2 > 0,
                source + ": triangle " + std::to_string(t) + " at " + formatPoint(a) +
                    " m is degenerate (zero area); expected a clean closed surface");
  }

  // 2. edges: each undirected edge used exactly twice, in opposite directions
  std::vector<EdgeUse> uses;
  uses.reserve(3 * nt);
  for (int t = 0; t < nt; ++t) {
    for (int k = 0; k < 3; ++k) {
      const int a = surface.triangles[t][k], b = surface.triangles[t][(k + 1) % 3];
      uses.push_back({std::min(a, b), std::max(a, b), a < b, t});
    }
  }
  std::sort(uses.begin(), uses.end());
  int boundary = 0, nonManifold = 0, flipped = 0;
  std::string boundaryExample, nonManifoldExample, flippedExample;
  for (size_t i = 0; i < uses.size();) {
    size_t j = i;
    while (j < uses.size() && uses[j].lo == uses[i].lo && uses[j].hi == uses[i].hi) ++j;
    const int count = static_cast<int>(j - i);
    const std::string where = formatEdge(surface, uses[i].lo, uses[i].hi);
    if (count == 1) {
      if (boundary++ == 0) boundaryExample = where;
    } else if (count > 2) {
      if (nonManifold++ == 0) {
        nonManifoldExample = where + " (in " + std::to_string(count) + " triangles)";
      }
    } else if (uses[i].forward == uses[i + 1].forward) {
      if (flipped++ == 0) {
        flippedExample = where + " (triangles " + std::to_string(uses[i].triangle) + " and " +
                         std::to_string(uses[i + 1].triangle) + ")";
      }
    }
    i = j;
  }
  ESIM_VERIFY(boundary == 0, source + ": surface is not closed: " + std::to_string(boundary) +
                                 " boundary edges (used by one triangle only), e.g. " +
                                 boundaryExample + "; expected a watertight surface");
  ESIM_VERIFY(nonManifold == 0,
              source + ": surface is non-manifold: " + std::to_string(nonManifold) +
                  " edges shared by more than two triangles, e.g. " + nonManifoldExample +
                  "; expected every edge in exactly two triangles");
  ESIM_VERIFY(flipped == 0,
              source + ": surface orientation is inconsistent: " + std::to_string(flipped) +
                  " edges whose two triangles run the same way, e.g. " + flippedExample +
                  "; expected all triangles counter-clockwise seen from outside");

  // 3. vertex-manifold: the triangles around each vertex form one fan
  std::vector<std::vector<std::array<int, 2>>> link(nv);  // per vertex: (next, prev) edges
  for (const Tri& t : surface.triangles) {
    for (int k = 0; k < 3; ++k) link[t[k]].push_back({t[(k + 1) % 3], t[(k + 2) % 3]});
  }
  for (int v = 0; v < nv; ++v) {
    auto& fan = link[v];
    if (fan.empty()) continue;
    std::sort(fan.begin(), fan.end());
    // walk next -> prev around the vertex starting at the first triangle
    int steps = 0, at = fan[0][0];
    do {
      const auto it = std::lower_bound(fan.begin(), fan.end(), std::array<int, 2>{at, -1});
      if (it == fan.end() || (*it)[0] != at) break;
      at = (*it)[1];
      ++steps;
    } while (at != fan[0][0] && steps <= static_cast<int>(fan.size()));
    ESIM_VERIFY(steps == static_cast<int>(fan.size()),
                source + ": surface is non-manifold at vertex " + formatPoint(surface.vertices[v]) +
                    " m (" + std::to_string(fan.size()) +
                    " triangles meet there in more than one fan); expected a 2-manifold");
  }

  // 4. no self-intersections (CGAL)
  cgal::SelfIntersections hits;
  try {
    hits = cgal::findSelfIntersections(surface);
  } catch (const Error& e) {
    throw Error(source + ": " + e.what());
  }
  if (hits.pairCount > 0) {
    const Tri& ta = surface.triangles[hits.first[0]];
    const Vec3 centre =
        (surface.vertices[ta[0]] + surface.vertices[ta[1]] + surface.vertices[ta[2]]) / 3.0;
    throw Error(source + ": surface self-intersects (" + std::to_string(hits.pairCount) +
                " pairs of faces), e.g. faces " + std::to_string(hits.first[0]) + " and " +
                std::to_string(hits.first[1]) + " (face " + std::to_string(hits.first[0]) +
                " centred at " + formatPoint(centre) +
                " m); expected a surface that bounds a single volume");
  }

  // 5. it must enclose something
  ESIM_VERIFY(std::abs(enclosedVolume(surface)) > 0, source + ": surface encloses zero volume");
}

void orientOutward(SurfaceMesh& surface) {
  if (enclosedVolume(surface) >= 0) return;
  for (Tri& t : surface.triangles) std::swap(t[1], t[2]);
}

// ---- meshing ----
std::string slabTooLarge(const SlabSpec& spec) {
  const std::array<int, 3> p = slabNodesPerAxis(spec);
  const double tets = 6.0 * (p[0] - 1) * (p[1] - 1) * (p[2] - 1);
  if (tets <= kMaxSceneTets) return "";
  std::ostringstream msg;
  msg << "gives a grid of " << p[0] << " x " << p[1] << " x " << p[2] << " nodes, "
      << static_cast<long long>(tets) << " tetrahedra; at most "
      << static_cast<long long>(kMaxSceneTets)
      << " (a scene's bound: meshing and factorizing more takes hours and more memory than a "
         "workstation has)";
  return msg.str();
}

MeshingOptions checkMeshing(const SurfaceMesh& surface, const MeshingOptions& options,
                            const std::string& sourceName) {
  // 1. options, derived sizes
  MeshingOptions opt = options;
  auto positive = [](double x) { return std::isfinite(x) && x > 0; };
  ESIM_VERIFY(positive(opt.cellSizeM),
              sourceName + ": cell size must be > 0 m (got " + std::to_string(opt.cellSizeM) + ")");
  if (opt.facetSizeM == 0) opt.facetSizeM = opt.cellSizeM;
  if (opt.facetDistanceM == 0) opt.facetDistanceM = opt.cellSizeM / 20;
  if (opt.edgeSizeM == 0) opt.edgeSizeM = opt.facetSizeM;
  ESIM_VERIFY(positive(opt.facetSizeM) && positive(opt.facetDistanceM) && positive(opt.edgeSizeM),
              sourceName + ": facet size, facet distance and edge size must be > 0 m");
  ESIM_VERIFY(opt.facetAngleDeg > 0 && opt.facetAngleDeg <= 30,
              sourceName +
                  ": facet angle must be in (0, 30] degrees (Mesh_3 terminates only "
                  "then), got " +
                  std::to_string(opt.facetAngleDeg));
  ESIM_VERIFY(opt.cellRadiusEdgeRatio >= 2,
              sourceName +
                  ": cell radius-edge ratio must be >= 2 (Mesh_3 terminates only "
                  "then), got " +
                  std::to_string(opt.cellRadiusEdgeRatio));
  ESIM_VERIFY(opt.featureAngleDeg >= 0 && opt.featureAngleDeg < 180 && opt.sliverBoundDeg >= 0 &&
                  opt.sliverBoundDeg < 70.5 && opt.lloydIterations >= 0,
              sourceName + ": feature angle, sliver bound or Lloyd iterations out of range");
  const MeshingOptions::Refinement& ref = opt.refinement;
  if (ref.enabled) {
    ESIM_VERIFY(positive(ref.cellSizeM) && ref.cellSizeM <= opt.cellSizeM,
                sourceName + ": refinement cell size must be > 0 m and <= the cell size " +
                    std::to_string(opt.cellSizeM) + " m (got " + std::to_string(ref.cellSizeM) +
                    ")");
    ESIM_VERIFY(positive(ref.widthM), sourceName + ": refinement width must be > 0 m (got " +
                                          std::to_string(ref.widthM) + ")");
    ESIM_VERIFY(ref.fromM.allFinite() && ref.toM.allFinite() && ref.fromM != ref.toM,
                sourceName + ": refinement segment needs two distinct finite ends (from " +
                    formatPoint(ref.fromM) + " to " + formatPoint(ref.toM) + " m)");
  }

  // 2. size guard: a unit mix-up (mm read as m) would otherwise mesh for hours
  const double volume = std::abs(enclosedVolume(surface));
  const double regularTetPerR3 = 8.0 / (9.0 * std::sqrt(3.0));  // volume / circumradius^3
  double expectedTets = volume / (regularTetPerR3 * std::pow(opt.cellSizeM, 3));
  if (ref.enabled) {  // plus the fine zone: a capsule of radius 2 widthM around the segment
    const double rr = 2 * ref.widthM;
    const double capsule = std::numbers::pi * rr * rr * (ref.toM - ref.fromM).norm() +
                           4.0 / 3.0 * std::numbers::pi * rr * rr * rr;
    expectedTets += std::min(capsule, volume) / (regularTetPerR3 * std::pow(ref.cellSizeM, 3));
  }
  if (expectedTets > kMaxSceneTets) {
    std::ostringstream msg;
    msg << sourceName << ": cell size " << opt.cellSizeM << " m";
    if (ref.enabled) msg << " (" << ref.cellSizeM << " m near the refinement segment)";
    msg << " would give about " << expectedTets << " tetrahedra for an enclosed volume of "
        << volume
        << " m^3; check the units (the surface must be in metres) or use a larger cell size";
    throw Error(msg.str());
  }
  return opt;
}

TetMesh tetrahedralize(const SurfaceMesh& surface, const MeshingOptions& options,
                       const std::string& sourceName) {
  const MeshingOptions opt = checkMeshing(surface, options, sourceName);  // 1-2
  // 3. Mesh_3, then checks
  TetMesh mesh;
  try {
    mesh = cgal::generateTets(surface, opt);
  } catch (const Error& e) {
    throw Error(sourceName + ": " + e.what());
  }
  validateMesh(mesh, sourceName + " (tetrahedralized)");
  mesh.nodeSets["boundary"] = boundaryNodes(mesh, boundaryFaces(mesh));
  return mesh;
}

namespace {
// readSurface -> checkSurface -> orientOutward
SurfaceMesh checkedSurface(const std::string& path, double scaleToMetres) {
  SurfaceMesh surface = readSurface(path, scaleToMetres);
  checkSurface(surface, path);
  orientOutward(surface);
  return surface;
}
}  // namespace

TetMesh loadTetMesh(const std::string& path, const MeshingOptions& options, double scaleToMetres) {
  return tetrahedralize(checkedSurface(path, scaleToMetres), options, path);
}

void checkTetMeshSource(const std::string& path, const MeshingOptions& options,
                        double scaleToMetres) {
  checkMeshing(checkedSurface(path, scaleToMetres), options, path);
}

}  // namespace esim
