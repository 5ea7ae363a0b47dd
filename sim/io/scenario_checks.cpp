// scenario_checks.cpp - the cross-field rules of a scenario (see scenario_checks.h).
//
// After the Reader has checked every field alone, checkScenario checks the rules between
// fields, in this order: the tool path file (read into tool.path); phase dependencies and the
// effects and heat sources they need; the mesh (grid sizes, the planned cut, refinement, the mesh
// file, resolved through resolveAsset); the frame count; the camera; the look (colour ranges, even
// video sizes, MSAA). The first broken rule throws, located at the field it names.
#include "sim/io/scenario_checks.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "sim/core_error.h"
#include "sim/io/mesh_import.h"
#include "sim/io/scenario.h"
#include "sim/io/scenario_format.h"
#include "sim/message_text.h"

namespace esim::scenario_detail {

std::string phaseList(const Scenario& s) {
  std::string out;
  for (Phase p : s.physics) out += (out.empty() ? "" : ", ") + std::string(phaseName(p));
  return "[" + out + "]";
}

namespace {

namespace fs = std::filesystem;

// a file named by `key` (mesh.file.path, tool.path_file) resolved: the scenario's folder, the
// nearest ancestor holding assets/ (the repository root), then the working directory;
// `expected` says what the file should be
std::string resolveAsset(const std::string& path, const std::string& sourceName,
                         const Reader& reader, const std::string& key,
                         const std::string& expected) {
  const fs::path p(path);
  std::vector<fs::path> tried;
  if (p.is_absolute()) {
    tried.push_back(p);
  } else {
    const fs::path dir = fs::path(sourceName).parent_path();
    tried.push_back(dir / p);
    std::error_code ec;
    fs::path up = fs::absolute(dir.empty() ? fs::path(".") : dir, ec).lexically_normal();
    while (!ec && !up.empty()) {
      std::error_code statError;  // a missing assets/ is no error
      if (fs::is_directory(up / "assets", statError)) {
        tried.push_back(up / p);
        break;
      }
      if (up == up.parent_path()) break;
      up = up.parent_path();
    }
    tried.push_back(fs::current_path(ec) / p);
  }
  std::vector<std::string> names;
  for (const auto& t : tried) {
    std::error_code ec;
    const fs::path full = fs::absolute(t, ec).lexically_normal();
    if (fs::is_regular_file(full, ec)) return full.string();
    if (fs::exists(full, ec))  // it said "not found" of a folder or a device
      reader.fail(key, key + ": '" + printableInMessage(full.string()) + "' is " +
                           (fs::is_directory(full, ec) ? "a folder" : "not a regular file") +
                           "; expected " + expected);
    const std::string n = printableInMessage(full.string());
    if (std::find(names.begin(), names.end(), n) == names.end()) names.push_back(n);
  }
  reader.fail(
      key, key + ": file '" + printableInMessage(path) + "' not found; tried " + joinList(names));
}

// tool.path_file read into s.tool.path: each line's numbers checked as tool.path's entries
// are, named by file and line. Given with tool.path, the one set by an override (--set, a
// sweep's value) replaces the one in the file; both in the file, or both overrides, is an
// error.
void readToolPathFile(Scenario& s, const Reader& r) {
  const std::string key = "tool.path_file";
  if (r.marks().count("tool.path")) {
    const bool fileSet = r.fromOverride(key), listSet = r.fromOverride("tool.path");
    if (listSet && !fileSet) {  // the list given by an override replaces the file
      s.tool.pathFile.clear();
      return;
    }
    if (fileSet == listSet)
      r.fail(key, key +
                      " and tool.path are both given; give one (the file's keyframes replace "
                      "the list)");
  }
  const std::string file = resolveAsset(s.tool.pathFile, s.sourceName, r, key,
                                        "a CSV file of keyframes (t_s, x_m, y_m, z_m a line)");
  s.tool.pathFileResolved = file;
  const std::string shown = printableInMessage(file);  // the file as named in messages
  std::ifstream stream(file, std::ios::binary);
  if (!stream) r.fail(key, key + ": cannot open '" + shown + "'");
  // read whole, bounded (a regular file can be endless: /proc/kcore)
  constexpr size_t kMaxBytes = size_t{64} << 20;  // ~3 million keyframes
  std::string text;
  if (!readAtMost(stream, file, kMaxBytes, text))
    r.fail(key,
           key + ": '" + shown +
               "' is more than 64 MiB; expected a CSV of keyframes (t_s, x_m, y_m, z_m a line)");
  std::istringstream in(text);
  const auto& schema = keyframeSchema();  // t_s, position_m, orientation_deg
  static const char* const kColumns[7] = {"t_s", "x_m", "y_m", "z_m", "rx_deg", "ry_deg", "rz_deg"};
  std::vector<ScenarioKeyframe> keys;
  int lineNo = 0;
  for (std::string line; std::getline(in, line);) {
    ++lineNo;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const size_t first = line.find_first_not_of(" \t");
    if (first == std::string::npos || line[first] == '#') continue;
    const std::string at = key + ": " + shown + ":" + std::to_string(lineNo) + ": ";
    std::vector<std::string> cells;
    std::stringstream ss(line);
    for (std::string c; std::getline(ss, c, ',');) {
      const size_t b = c.find_first_not_of(" \t"), e = c.find_last_not_of(" \t");
      cells.push_back(b == std::string::npos ? "" : c.substr(b, e - b + 1));
    }
    if (keys.empty() && !cells.empty() && cells[0] == kColumns[0]) {  // the names' line
      if ((cells.size() != 4 && cells.size() != 7) ||
          !std::equal(cells.begin(), cells.end(), kColumns))
        r.fail(key, at + "expected the names t_s,x_m,y_m,z_m (and rx_deg,ry_deg,rz_deg), got " +
                        quoteInMessage(line));
      continue;
    }
    if (cells.size() != 4 && cells.size() != 7)
      r.fail(key, at +
                      "expected 4 numbers (t_s, x_m, y_m, z_m) or 7 (and rx_deg, ry_deg, "
                      "rz_deg), got " +
                      std::to_string(cells.size()) + " fields");
    double v[7] = {0, 0, 0, 0, 0, 0, 0};
    for (size_t c = 0; c < cells.size(); ++c) {
      const Range& range = schema[c == 0 ? 0 : c < 4 ? 1 : 2].range;
      char* end = nullptr;
      errno = 0;
      v[c] = std::strtod(cells[c].c_str(), &end);
      if (cells[c].empty() || *end != '\0' || errno == ERANGE || !std::isfinite(v[c]))
        r.fail(key, at + kColumns[c] + " = " + quoteInMessage(cells[c]) +
                        ": expected a finite number in " + formatRange(range));
      if (!range.contains(v[c]))
        r.fail(key,
               at + kColumns[c] + " = " + formatNumber(v[c]) + " is outside " + formatRange(range));
    }
    ScenarioKeyframe k;
    k.timeS = v[0];
    k.positionM = Vec3(v[1], v[2], v[3]);
    k.orientationDeg = Vec3(v[4], v[5], v[6]);
    if (!keys.empty() && !(k.timeS > keys.back().timeS))
      r.fail(key, at + "t_s = " + formatNumber(k.timeS) + " is not after the line before's " +
                      formatNumber(keys.back().timeS) + "; keyframe times must strictly increase");
    keys.push_back(k);
  }
  if (keys.empty()) r.fail(key, key + ": '" + shown + "' holds no keyframe (t_s, x_m, y_m, z_m)");
  s.tool.path = std::move(keys);
}

// physics: each phase has the phases it builds on, and a heat source
void checkPhases(const Scenario& s, const Reader& r) {
  const bool electric = s.has(Phase::Electric), thermal = s.has(Phase::Thermal);
  const std::string problem = phaseDependencyProblem(phaseSet(s));  // the core's rule
  if (!problem.empty()) r.fail("physics", "physics " + phaseList(s) + ": " + problem);
  if (thermal && !electric && s.heatSource.kind == HeatSourceKind::None &&
      !s.initialHotSpot.enabled)
    r.fail("physics", "physics " + phaseList(s) +
                          ": 'thermal' without 'electric' has no heat; add electric, or set "
                          "heat_source.kind: gaussian or initial_hot_spot.enabled: true");
  if (s.heatSource.kind != HeatSourceKind::None && (!thermal || electric))
    r.fail("heat_source.kind",
           "heat_source.kind = gaussian"
           " is used only when physics has thermal without electric "
           "(physics " +
               phaseList(s) + "); set heat_source.kind: none");
  if (s.initialHotSpot.enabled && !thermal)
    r.fail("initial_hot_spot.enabled",
           "initial_hot_spot.enabled needs the thermal phase (physics " + phaseList(s) + ")");
}

// effects need their phases
void checkEffects(const Scenario& s, const Reader& r) {
  const bool electric = s.has(Phase::Electric), thermal = s.has(Phase::Thermal);
  if (s.effects.temperatureDependentConductivity && !(electric && thermal))
    r.fail("effects.temperature_dependent_conductivity",
           "effects.temperature_dependent_conductivity needs electric and thermal (physics " +
               phaseList(s) + ")");
  if (s.effects.thermalDamage && !thermal)
    r.fail("effects.thermal_damage",
           "effects.thermal_damage needs thermal (physics " + phaseList(s) + ")");
  if (s.effects.surfaceCoolingHWPerM2K > 0 && !thermal)
    r.fail("effects.surface_cooling.h_w_per_m2k",
           "effects.surface_cooling.h_w_per_m2k > 0 needs thermal (physics " + phaseList(s) + ")");
  if (s.subgridContact.mode != SubgridMode::Off && !(electric && thermal))
    r.fail("subgrid_contact.mode",
           std::string("subgrid_contact.mode: ") + subgridModeName(s.subgridContact.mode) +
               " needs electric and thermal (physics " + phaseList(s) + "); set it off");
}

// grid sizes, the planned cut, refinement and the mesh file (resolved into
// s.mesh.file.resolvedPath)
void checkMesh(Scenario& s, const Reader& r) {
  const auto& npa = s.mesh.slab.nodesPerAxis;
  const bool allZero = npa[0] == 0 && npa[1] == 0 && npa[2] == 0;
  if (!allZero && (npa[0] < 2 || npa[1] < 2 || npa[2] < 2))
    r.fail("mesh.slab.nodes_per_axis",
           "mesh.slab.nodes_per_axis: each entry must be >= 2, or all 0 to derive the grid "
           "from mesh.slab.nodes");
  if (s.mesh.slab.grading.enabled && s.mesh.slab.grading.fromM == s.mesh.slab.grading.toM)
    r.fail("mesh.slab.grading.to_m",
           "mesh.slab.grading.to_m equals from_m; the planned cut needs two distinct ends");
  const ScenarioRefine& refine = s.mesh.file.refine;
  if (refine.enabled && refine.fromM == refine.toM)
    r.fail("mesh.file.refine.to_m",
           "mesh.file.refine.to_m equals from_m; the planned cut needs two distinct ends");
  if (refine.enabled && refine.cellSizeM > s.mesh.file.cellSizeM)
    r.fail("mesh.file.refine.cell_size_m",
           "mesh.file.refine.cell_size_m = " + formatNumber(refine.cellSizeM) +
               " m is larger than mesh.file.cell_size_m = " + formatNumber(s.mesh.file.cellSizeM) +
               " m; the refined cells must be at most the global size");
  if (s.mesh.source == MeshSource::Slab &&
      (allZero || (npa[0] >= 2 && npa[1] >= 2 && npa[2] >= 2))) {
    // the grid's tets, bounded like a file's predicted count
    if (const std::string problem = slabTooLarge(makeSlabSpec(s)); !problem.empty()) {
      const std::string key = allZero ? "mesh.slab.nodes" : "mesh.slab.nodes_per_axis";
      r.fail(key, key + " " + problem);
    }
  }
  if (s.mesh.source == MeshSource::File) {
    if (s.mesh.file.path.empty())
      r.fail("mesh.source", "mesh.source = file needs mesh.file.path (a surface file)");
    s.mesh.file.resolvedPath = resolveAsset(s.mesh.file.path, s.sourceName, r, "mesh.file.path",
                                            "a closed surface file (OBJ, STL, PLY or glTF)");
  }
}

// frame count, camera
void checkTimeAndCamera(const Scenario& s, const Reader& r) {
  if (std::lround(s.time.durationS * s.time.fps) < 1)
    r.fail("time.duration_s",
           "time.duration_s * time.fps = " + formatNumber(s.time.durationS * s.time.fps) +
               " gives no frame; at least one frame is needed");
  const Vec3 view = s.camera.targetM - s.camera.eyeM;
  if (view.norm() == 0.0)
    r.fail("camera.target_m", "camera.target_m equals camera.eye_m; the camera needs a direction");
  // the renderer's tolerance (render/renderer.cpp), so that run never refuses what passed here
  if (!(view.normalized().cross(s.camera.up.normalized()).norm() > 1e-3))
    r.fail("camera.up", "camera.up is parallel to the view direction (target_m - eye_m)");
}

// colour ranges, video size, MSAA
void checkLook(const Scenario& s, const Reader& r) {
  const bool electric = s.has(Phase::Electric);
  if (!(s.look.tMaxC > s.look.tMinC))
    r.fail("look.t_max_c", "look.t_max_c = " + formatNumber(s.look.tMaxC) +
                               " must be above look.t_min_c = " + formatNumber(s.look.tMinC));
  if (s.look.style == "potential" && !electric)
    r.fail("look.style", "look.style = potential needs the electric phase (physics " +
                             phaseList(s) + "); add electric, or use temperature or tissue");
  const double vMaxV = s.look.vMaxV != 0.0 ? s.look.vMaxV : s.tool.voltageV;
  if ((s.look.style == "potential" || s.look.vMaxV != 0.0) && !(vMaxV > s.look.vMinV))
    r.fail(s.look.vMaxV != 0.0 ? "look.v_max_v" : "look.v_min_v",
           "look.v_max_v = " + formatNumber(vMaxV) +
               (s.look.vMaxV != 0.0 ? "" : " (0 = tool.voltage_v)") +
               " must be above look.v_min_v = " + formatNumber(s.look.vMinV));
  if (s.look.potentialScale == "log" && !(s.look.vMinV > 0.0))
    r.fail("look.v_min_v", "look.v_min_v = " + formatNumber(s.look.vMinV) +
                               " must be above 0 with look.potential_scale = log");
  if (s.look.width % 2 != 0)
    r.fail("look.width",
           "look.width = " + std::to_string(s.look.width) + " must be even (yuv420p video)");
  if (s.look.height % 2 != 0)
    r.fail("look.height",
           "look.height = " + std::to_string(s.look.height) + " must be even (yuv420p video)");
  if (s.look.msaa == 1 || s.look.msaa == 3)
    r.fail("look.msaa", "look.msaa = " + std::to_string(s.look.msaa) + " must be 0, 2 or 4");
}

}  // namespace

void checkScenario(Scenario& s, const Reader& r) {
  if (!s.tool.pathFile.empty()) readToolPathFile(s, r);
  checkPhases(s, r);
  checkEffects(s, r);
  checkMesh(s, r);
  checkTimeAndCamera(s, r);
  checkLook(s, r);
}

}  // namespace esim::scenario_detail
