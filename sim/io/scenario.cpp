// scenario.cpp - the scenario public API: loading and the values derived from a scenario.
//
// parseScenario runs the steps: parse the YAML text, merge the --set overrides, read
// every key against the schema (scenario_reader.cpp), then the cross-field rules
// (scenario_checks.cpp); loadScenario reads the file first. The derived values (frame
// count, slab spec, meshing options, tool path, one-line summary) follow. The other
// parts of the scenario code, by file:
//   scenario_schema.h/.cpp   the schema table: key, type, unit, range/choices, description
//   scenario_format.h/.cpp   numbers and values as YAML text
//   scenario_reader.h/.cpp   YAML tree -> Scenario with file:line:col errors and suggestions
//   scenario_checks.h/.cpp   cross-field rules (phase dependencies, assets, camera, ...)
//   scenario_writer.cpp      resolved YAML, hash, field list and reference markdown
#include "sim/io/scenario.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>

#include "sim/core_error.h"
#include "sim/io/scenario_checks.h"
#include "sim/io/scenario_format.h"
#include "sim/io/scenario_reader.h"
#include "sim/message_text.h"

namespace esim {

using namespace scenario_detail;

bool Scenario::has(Phase p) const {
  return std::find(physics.begin(), physics.end(), p) != physics.end();
}

PhaseSet phaseSet(const Scenario& s) {
  PhaseSet p;
  p.electric = s.has(Phase::Electric);
  p.thermal = s.has(Phase::Thermal);
  p.boiling = s.has(Phase::Boiling);
  p.structural = s.has(Phase::Structural);
  p.rupture = s.has(Phase::Rupture);
  return p;
}

const char* phaseName(Phase phase) {
  switch (phase) {
    case Phase::Electric:
      return "electric";
    case Phase::Thermal:
      return "thermal";
    case Phase::Boiling:
      return "boiling";
    case Phase::Structural:
      return "structural";
    case Phase::Rupture:
      return "rupture";
  }
  return "?";
}

namespace {

// the offset of the first byte of `text` that does not start or continue a well-formed UTF-8
// sequence (RFC 3629: no overlong forms, no surrogates, nothing above U+10FFFF), or npos
size_t firstNonUtf8(const std::string& text) {
  const auto* b = reinterpret_cast<const unsigned char*>(text.data());
  const size_t n = text.size();
  for (size_t i = 0; i < n;) {
    const unsigned c = b[i];
    int more = 0;
    unsigned low = 0x80, high = 0xBF;  // the allowed range of the second byte
    if (c < 0x80) {
      ++i;
      continue;
    } else if (c >= 0xC2 && c <= 0xDF) {
      more = 1;
    } else if (c >= 0xE0 && c <= 0xEF) {
      more = 2;
      if (c == 0xE0) low = 0xA0;   // (overlong)
      if (c == 0xED) high = 0x9F;  // (surrogates)
    } else if (c >= 0xF0 && c <= 0xF4) {
      more = 3;
      if (c == 0xF0) low = 0x90;   // (overlong)
      if (c == 0xF4) high = 0x8F;  // (above U+10FFFF)
    } else {
      return i;
    }
    for (int k = 1; k <= more; ++k) {
      if (i + k >= n) return i;
      const unsigned d = b[i + k];
      if (k == 1 ? (d < low || d > high) : (d < 0x80 || d > 0xBF)) return i;
    }
    i += more + 1;
  }
  return std::string::npos;
}

// the offset of the first C0 control character other than tab, line feed and carriage return,
// or of DEL, or npos: YAML 1.2 (5.1) allows none in a stream. yaml-cpp read a text that starts
// with a NUL byte (or has one second) as UTF-16 or UTF-32, and made of it a name that was no
// longer UTF-8: the scenario the run then wrote out (scenario.yaml) could not be read back
size_t firstControl(const std::string& text) {
  for (size_t i = 0; i < text.size(); ++i) {
    const auto c = static_cast<unsigned char>(text[i]);
    if ((c < 0x20 && c != '\t' && c != '\n' && c != '\r') || c == 0x7F) return i;
  }
  return std::string::npos;
}

}  // namespace

void requireUtf8Text(const std::string& text, const std::string& where, bool lineAndColumn) {
  const size_t bad = firstNonUtf8(text);
  const size_t control = firstControl(text);
  const size_t at = std::min(bad, control);
  if (at == std::string::npos) return;
  std::string place = where;
  if (lineAndColumn) {
    const size_t newline = at == 0 ? std::string::npos : text.rfind('\n', at - 1);
    const size_t line = 1 + std::count(text.begin(), text.begin() + static_cast<long>(at), '\n');
    const size_t column = at - (newline == std::string::npos ? 0 : newline + 1) + 1;
    // appended piece by piece: GCC 12 took ":" + std::to_string(line) for an overlapping
    // memcpy (a -Wrestrict false positive in char_traits.h)
    place += ':';
    place += std::to_string(line);
    place += ':';
    place += std::to_string(column);
  }
  char byte[8];
  std::snprintf(byte, sizeof byte, "0x%02X", static_cast<unsigned char>(text[at]));
  if (at == control)
    throw Error(place + ": a control character (byte " + byte +
                ") that YAML does not allow in text; write it as an escape in a double-quoted "
                "string (\"\\x" +
                std::string(byte + 2) + "\") or remove it");
  throw Error(place + ": not UTF-8 text (byte " + byte + "); YAML is Unicode: save it as UTF-8");
}

std::string decodedTextProblem(const std::string& value) {
  const size_t bad = firstNonUtf8(value);
  if (bad == std::string::npos) return "";
  char byte[8];
  std::snprintf(byte, sizeof byte, "0x%02X", static_cast<unsigned char>(value[bad]));
  return std::string("the text is not UTF-8 once its escapes are decoded (byte ") + byte +
         " at byte " + std::to_string(bad + 1) +
         "; YAML's \\N is one: write U+0085 as \\x85, or leave it out)";
}

Scenario parseScenario(const std::string& yamlText, const std::string& sourceName,
                       const std::vector<std::string>& overrides) {
  // 1. parse
  requireUtf8Text(yamlText, sourceName, true);
  for (const auto& text : overrides) requireUtf8Text(text, sourceName + ": --set", false);
  YAML::Node root;
  try {
    root = YAML::Load(yamlText);
  } catch (const YAML::ParserException& e) {
    throw Error(sourceName + ":" + std::to_string(e.mark.line + 1) + ":" +
                std::to_string(e.mark.column + 1) +
                ": malformed YAML: " + printableInMessage(e.msg));
  } catch (const YAML::Exception& e) {
    throw Error(sourceName + ": malformed YAML: " + printableInMessage(e.msg));
  }
  // a sweep file given where a scenario was expected (esim run scenarios/sweeps/x.yaml): said
  // so, rather than "base: unknown key"
  if (root.IsMap() && root["base"] &&
      (root["grid"] || root["random"] || root["draws"] || root["set"])) {
    const YAML::Mark m = root["base"].Mark();
    throw Error(sourceName + ":" + std::to_string(m.line + 1) +
                ": base: this looks like a sweep file (base, with grid, random, draws or set), "
                "not a scenario: run its variants with esim sweep " +
                sourceName + " -o DIR (scenarios/sweeps/README.md)");
  }
  // 2. overrides
  Reader reader(sourceName);
  for (const auto& text : overrides) applyOverride(root, text, sourceName, reader);
  // 3. keys, types, ranges
  Scenario s;
  s.sourceName = sourceName;
  try {
    reader.readGroup(root, "", s);
  } catch (const YAML::Exception& e) {  // defensive: yaml-cpp errors not caught above
    throw Error(sourceName + ": " + printableInMessage(e.msg));
  }
  // 4. cross-field rules
  checkScenario(s, reader);
  return s;
}

bool readAtMost(std::istream& in, const std::string& name, size_t maxBytes, std::string& text) {
  text.clear();
  char chunk[1 << 16];
  while (in.read(chunk, sizeof chunk) || in.gcount() > 0) {
    text.append(chunk, static_cast<size_t>(in.gcount()));
    if (text.size() > maxBytes) return false;
  }
  if (in.bad()) throw Error(name + ": read failed", ErrorKind::Run);
  return true;
}

std::string readYamlText(std::istream& in, const std::string& name, const std::string& what) {
  std::string text;
  if (!readAtMost(in, name, kMaxYamlBytes, text))
    throw Error(name + ": more than " + std::to_string(kMaxYamlBytes >> 20) + " MiB; a " + what +
                " is a short YAML file (is this the right file?)");
  return text;
}

Scenario loadScenario(const std::string& path, const std::vector<std::string>& overrides) {
  if (path == "-") {
    // standard input, read once (stdin cannot be read again: a bench that loads the scene
    // per size got an empty scenario, i.e. the defaults, the second time)
    static const std::string text = readYamlText(std::cin, "<stdin>", "scenario");
    return parseScenario(text, "<stdin>", overrides);
  }
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec))
    throw Error(path + ": is a folder; expected a scenario file (YAML, e.g. scenarios/*.yaml)");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(path + ": cannot open the scenario file");
  return parseScenario(readYamlText(in, path, "scenario"), path, overrides);
}

int frameCount(const Scenario& s) {
  return std::max(1, static_cast<int>(std::lround(s.time.durationS * s.time.fps)));
}

SlabSpec makeSlabSpec(const Scenario& s) {
  SlabSpec spec;
  spec.sizeM = s.mesh.slab.sizeM;
  spec.targetNodes = s.mesh.slab.nodes;
  spec.nodesPerAxis = s.mesh.slab.nodesPerAxis;
  const ScenarioGrading& g = s.mesh.slab.grading;
  spec.grading.enabled = g.enabled;
  spec.grading.cutFrom = g.fromM;
  spec.grading.cutTo = g.toM;
  spec.grading.ratio = g.ratio;
  spec.grading.widthM = g.widthM;
  spec.grading.towardTop = g.towardTop;
  return spec;
}

MeshingOptions makeMeshingOptions(const Scenario& s) {
  const ScenarioMeshFile& f = s.mesh.file;
  MeshingOptions o;
  o.cellSizeM = f.cellSizeM;
  o.facetSizeM = f.facetSizeM;
  o.facetDistanceM = f.facetDistanceM;
  o.facetAngleDeg = f.facetAngleDeg;
  o.cellRadiusEdgeRatio = f.radiusEdgeRatio;
  o.refinement.enabled = f.refine.enabled;
  o.refinement.fromM = f.refine.fromM;
  o.refinement.toM = f.refine.toM;
  o.refinement.cellSizeM = f.refine.cellSizeM;
  o.refinement.widthM = f.refine.widthM;
  return o;
}

ToolPath makeToolPath(const Scenario& s) {
  ToolPath path;
  for (const auto& k : s.tool.path)
    path.keys.push_back({k.timeS, k.positionM, eulerXyzDegToQuaternion(k.orientationDeg)});
  for (const auto& iv : s.tool.generatorOnS) path.generatorOnS.emplace_back(iv[0], iv[1]);
  validateToolPath(path);
  return path;
}

std::string scenarioSummary(const Scenario& s) {
  std::ostringstream out;
  out << frameCount(s) << " frames (" << formatNumber(s.time.durationS) << " s at "
      << formatNumber(s.time.fps) << " fps), physics " << phaseList(s) << ", mesh ";
  if (s.mesh.source == MeshSource::Slab) {
    const auto& sz = s.mesh.slab.sizeM;
    out << "slab " << formatNumber(sz.x() * 1e3) << "x" << formatNumber(sz.y() * 1e3) << "x"
        << formatNumber(sz.z() * 1e3) << " mm, ";
    const auto& n = s.mesh.slab.nodesPerAxis;
    if (n[0] > 0)
      out << n[0] << "x" << n[1] << "x" << n[2] << " nodes";
    else
      out << "~" << s.mesh.slab.nodes << " nodes";
    if (s.mesh.slab.grading.enabled) out << " graded x" << formatNumber(s.mesh.slab.grading.ratio);
  } else {
    out << "file " << s.mesh.file.path << " (cell " << formatNumber(s.mesh.file.cellSizeM * 1e3)
        << " mm";
    if (s.mesh.file.refine.enabled)
      out << ", " << formatNumber(s.mesh.file.refine.cellSizeM * 1e3) << " mm near the cut";
    out << ")";
  }
  out << ", tool " << (s.tool.shape == ElectrodeKind::Sphere ? "sphere" : "blade") << " "
      << formatNumber(s.tool.voltageV) << " V, " << s.tool.path.size() << " keyframe"
      << (s.tool.path.size() == 1 ? "" : "s") << ", look " << s.look.style;
  return out.str();
}

}  // namespace esim
