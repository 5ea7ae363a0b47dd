// sweep_spec.cpp - a sweep file read, checked and expanded into variants (see sweep_spec.h).
//
// Outline:
//   ---- text ----       numbers and YAML values as text, YAML -> JSON
//   ---- reading ----    the sweep file's keys with file:line:col errors
//   ---- draws ----      the portable random draws
//   ---- expansion ----  each variant: overrides, draws, path transforms, the checked scenario
#include "tools/app/sweep_spec.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <set>
#include <sstream>

#include "sim/core_error.h"
#include "sim/message_text.h"
#include "tools/app/json_text.h"
#include "tools/app/run_config.h"

namespace esim::app {

namespace {

namespace fs = std::filesystem;

constexpr std::size_t kMaxVariants = 1000000;
const char* const kPathOffset = "path.offset_m";
const char* const kPathAngle = "path.angle_deg";
const char* const kPathSpeed = "path.speed";

bool isPathKnob(const std::string& key) {
  return key == kPathOffset || key == kPathAngle || key == kPathSpeed;
}

// ---- text ----

// shortest text that reads back to the same double
std::string numberText(double v) {
  if (v == 0) return "0";  // no "-0"
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

std::string vectorText(const std::vector<double>& v) {
  std::string s = "[";
  for (std::size_t i = 0; i < v.size(); ++i) s += (i ? ", " : "") + numberText(v[i]);
  return s + "]";
}

std::string vec3Text(const Vec3& v) { return vectorText({v.x(), v.y(), v.z()}); }

// a YAML value as one line of flow YAML (what --set takes after '=')
std::string flowText(const YAML::Node& n) {
  YAML::Emitter e;
  e.SetSeqFormat(YAML::Flow);
  e.SetMapFormat(YAML::Flow);
  e << n;
  return e.c_str();
}

// two flow texts that give a scenario key the same value: equal text, or equal numbers
// (10, 10.0 and 1e1)
bool sameValue(const std::string& a, const std::string& b) {
  if (a == b) return true;
  char *endA = nullptr, *endB = nullptr;
  const double x = std::strtod(a.c_str(), &endA), y = std::strtod(b.c_str(), &endB);
  return endA != a.c_str() && *endA == '\0' && endB != b.c_str() && *endB == '\0' && x == y;
}

std::string where(const std::string& file, const YAML::Mark& m) {
  if (m.is_null()) return file;
  return file + ":" + std::to_string(m.line + 1) + ":" + std::to_string(m.column + 1);
}

// a YAML value as JSON: plain scalars that read as integers, numbers or true/false become
// those, anything else a string
nlohmann::json toJson(const YAML::Node& n) {
  if (!n.IsDefined() || n.IsNull()) return nullptr;
  if (n.IsSequence()) {
    nlohmann::json a = nlohmann::json::array();
    for (const auto& item : n) a.push_back(toJson(item));
    return a;
  }
  if (n.IsMap()) {
    nlohmann::json o = nlohmann::json::object();
    for (const auto& kv : n) o[kv.first.Scalar()] = toJson(kv.second);
    return o;
  }
  const std::string& s = n.Scalar();
  if (n.Tag() == "!") return s;  // quoted: a string
  if (s == "true" || s == "false") return s == "true";
  long long i = 0;
  const auto ri = std::from_chars(s.data(), s.data() + s.size(), i);
  if (ri.ec == std::errc() && ri.ptr == s.data() + s.size()) return i;
  double d = 0;
  if (YAML::convert<double>::decode(n, d) && std::isfinite(d)) return d;
  return s;
}

// ---- suggestions ----

std::size_t editDistance(const std::string& a, const std::string& b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diag = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diag + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diag = up;
    }
  }
  return row[b.size()];
}

std::string closest(const std::string& word, const std::vector<std::string>& candidates) {
  std::string best;
  std::size_t bestDist = std::max<std::size_t>(2, word.size() / 3) + 1;
  for (const auto& c : candidates) {
    const std::size_t d = editDistance(word, c);
    if (d < bestDist) {
      bestDist = d;
      best = c;
    }
  }
  return best;
}

std::string joined(const std::vector<std::string>& items) {
  std::string s;
  for (const auto& i : items) s += (s.empty() ? "" : ", ") + i;
  return s;
}

// the scenario's field paths (keyframe sub-fields left out: tool.path is set whole)
const std::vector<std::string>& scenarioKeys() {
  static const std::vector<std::string> keys = [] {
    std::vector<std::string> k;
    for (const auto& f : scenarioFields())
      if (f.path.find('[') == std::string::npos) k.push_back(f.path);
    return k;
  }();
  return keys;
}

bool isScenarioKeyOrGroup(const std::string& key) {
  for (const auto& k : scenarioKeys())
    if (k == key ||
        (k.size() > key.size() && k.compare(0, key.size(), key) == 0 && k[key.size()] == '.'))
      return true;
  return false;
}

// ---- reading ----

class SpecReader {
 public:
  SpecReader(std::string file) : file_(std::move(file)) {}

  [[noreturn]] void fail(const YAML::Mark& m, const std::string& msg) const {
    throw Error(where(file_, m) + ": " + msg);
  }

  std::string at(const YAML::Mark& m) const { return where(file_, m); }

  // a number, with a located error
  double number(const YAML::Node& n, const std::string& what) const {
    double v = 0;
    if (!n.IsScalar() || !YAML::convert<double>::decode(n, v) || !std::isfinite(v))
      fail(n.Mark(), what + ": expected a number, got " + describe(n));
    return v;
  }

  // a number, or a list of 3 numbers: the components
  std::vector<double> numberOrTriple(const YAML::Node& n, const std::string& what) const {
    if (n.IsSequence()) {
      if (n.size() != 3)
        fail(n.Mark(), what +
                           ": expected a number or a list of 3 numbers [x, y, z], got a list "
                           "of " +
                           std::to_string(n.size()));
      return {number(n[0], what + "[0]"), number(n[1], what + "[1]"), number(n[2], what + "[2]")};
    }
    return {number(n, what)};
  }

  static std::string describe(const YAML::Node& n) {
    if (!n.IsDefined() || n.IsNull()) return "nothing";
    if (n.IsSequence()) return "a list";
    if (n.IsMap()) return "a mapping";
    return quoteInMessage(n.Scalar());
  }

  // the key of set:, grid: or random:: a scenario key path (a field or a group) or a path
  // transform
  void checkKey(const YAML::Node& keyNode, const std::string& section) const {
    const std::string key = keyNode.IsScalar() ? keyNode.Scalar() : "";
    if (key.empty()) fail(keyNode.Mark(), section + ": keys must be scenario key paths");
    if (isPathKnob(key) || isScenarioKeyOrGroup(key)) return;
    std::vector<std::string> all = scenarioKeys();
    all.insert(all.end(), {kPathOffset, kPathAngle, kPathSpeed});
    const std::string near = closest(key, all);
    std::string msg = nameInMessage(section + "." + key) + ": unknown scenario key";
    if (!near.empty()) {
      msg += "; did you mean '" + near + "'?";
    } else if (key.rfind("tool.path.", 0) == 0 || key.rfind("path.", 0) == 0) {
      msg +=
          "; the tool path varies through path.offset_m, path.angle_deg, path.speed "
          "(or tool.path set whole)";
    } else {
      msg +=
          " (docs/scenario-reference.md lists them; the tool path varies through "
          "path.offset_m, path.angle_deg and path.speed)";
    }
    fail(keyNode.Mark(), msg);
  }

  // a value of a path transform, checked here (its own range)
  void checkPathValue(const std::string& key, const YAML::Node& v, const std::string& what) const {
    if (key == kPathOffset) {
      if (!v.IsSequence() || v.size() != 3)
        fail(v.Mark(),
             what + ": expected a list of 3 numbers in metres [dx, dy, dz], got " + describe(v));
      for (std::size_t i = 0; i < 3; ++i) {
        const double d = number(v[i], what);
        if (std::fabs(d) > 10.0)
          fail(v[i].Mark(), what + " = " + numberText(d) + " is outside [-10, 10] m");
      }
    } else if (key == kPathAngle) {
      const double a = number(v, what);
      if (std::fabs(a) > 360.0)
        fail(v.Mark(), what + " = " + numberText(a) + " is outside [-360, 360] degrees");
    } else if (key == kPathSpeed) {
      const double s = number(v, what);
      if (!(s > 0.0 && s <= 100.0))
        fail(v.Mark(), what + " = " + numberText(s) + " is outside (0, 100] (a speed factor)");
    }
  }

  void readSet(const YAML::Node& n, SweepSpec& spec) const {
    if (n.IsNull()) return;
    if (!n.IsMap())
      fail(n.Mark(), "set: expected a mapping of scenario keys to values, got " + describe(n));
    for (const auto& kv : n) {
      checkKey(kv.first, "set");
      SweepKnob k;
      k.key = kv.first.Scalar();
      k.where = at(kv.first.Mark());
      k.source = KnobSource::Set;
      if (isPathKnob(k.key)) checkPathValue(k.key, kv.second, "set." + k.key);
      k.values.push_back(flowText(kv.second));
      k.valueWhere.push_back(at(kv.second.Mark().is_null() ? kv.first.Mark() : kv.second.Mark()));
      spec.knobs.push_back(k);
    }
  }

  void readGrid(const YAML::Node& n, SweepSpec& spec) const {
    if (n.IsNull()) return;
    if (!n.IsMap())
      fail(n.Mark(),
           "grid: expected a mapping of scenario keys to lists of values, got " + describe(n));
    for (const auto& kv : n) {
      checkKey(kv.first, "grid");
      SweepKnob k;
      k.key = kv.first.Scalar();
      k.where = at(kv.first.Mark());
      k.source = KnobSource::Grid;
      const YAML::Node& list = kv.second;
      if (!list.IsSequence() || list.size() == 0)
        fail(list.Mark().is_null() ? kv.first.Mark() : list.Mark(),
             "grid." + k.key + ": expected a non-empty list of values, got " +
                 (list.IsSequence() ? std::string("an empty list") : describe(list)));
      for (std::size_t i = 0; i < list.size(); ++i) {
        if (isPathKnob(k.key))
          checkPathValue(k.key, list[i], "grid." + k.key + "[" + std::to_string(i) + "]");
        const std::string value = flowText(list[i]);
        for (std::size_t j = 0; j < i; ++j)
          if (sameValue(k.values[j], value))
            fail(list[i].Mark(), "grid." + k.key + "[" + std::to_string(i) +
                                     "] = " + nameInMessage(value) + " repeats grid." + k.key +
                                     "[" + std::to_string(j) +
                                     "]; give each value once (a repeated value runs the same "
                                     "variants twice)");
        k.values.push_back(value);
        k.valueWhere.push_back(at(list[i].Mark()));
      }
      spec.knobs.push_back(k);
    }
  }

  // {uniform: [lo, hi]}, {integer: [lo, hi]}, {choice: [...]}, {jitter: d}
  void readDraw(const YAML::Node& keyNode, const YAML::Node& d, SweepKnob& k) const {
    const std::string what = "random." + k.key;
    const std::vector<std::string> kinds{"uniform", "integer", "choice", "jitter"};
    if (!d.IsMap() || d.size() != 1)
      fail(d.Mark().is_null() ? keyNode.Mark() : d.Mark(),
           what +
               ": expected one distribution {uniform: [lo, hi]}, {integer: [lo, hi]}, "
               "{choice: [a, b, ...]} or {jitter: d}, got " +
               describe(d));
    const YAML::Node kindNode = d.begin()->first;
    const YAML::Node arg = d.begin()->second;
    const std::string kind = kindNode.IsScalar() ? kindNode.Scalar() : "";
    if (std::find(kinds.begin(), kinds.end(), kind) == kinds.end()) {
      const std::string near = closest(kind, kinds);
      fail(kindNode.Mark(), what + ": unknown distribution " + quoteInMessage(kind) +
                                (near.empty() ? "" : "; did you mean '" + near + "'?") +
                                " expected one of " + joined(kinds));
    }
    const std::string sub = what + "." + kind;
    k.valueWhere.push_back(at(arg.Mark().is_null() ? kindNode.Mark() : arg.Mark()));
    if (kind == "choice") {
      k.draw = DrawKind::Choice;
      if (!arg.IsSequence() || arg.size() == 0)
        fail(arg.Mark(), sub + ": expected a non-empty list of values, got " + describe(arg));
      k.valueWhere.clear();
      for (std::size_t i = 0; i < arg.size(); ++i) {
        if (isPathKnob(k.key)) checkPathValue(k.key, arg[i], sub + "[" + std::to_string(i) + "]");
        k.values.push_back(flowText(arg[i]));
        k.valueWhere.push_back(at(arg[i].Mark()));
      }
      return;
    }
    if (kind == "jitter") {
      k.draw = DrawKind::Jitter;
      k.hi = numberOrTriple(arg, sub);
      for (double h : k.hi)
        if (h < 0) fail(arg.Mark(), sub + ": the half-width must not be negative");
      if (k.key == kPathAngle || k.key == kPathSpeed) {
        if (k.hi.size() != 1) fail(arg.Mark(), sub + ": " + k.key + " is a number, not a list");
      } else if (k.key == kPathOffset && k.hi.size() == 1) {
        k.hi.assign(3, k.hi[0]);
      }
      return;
    }
    k.draw = kind == "uniform" ? DrawKind::Uniform : DrawKind::Integer;
    if (!arg.IsSequence() || arg.size() != 2)
      fail(arg.Mark(), sub + ": expected [lo, hi], got " + describe(arg));
    k.lo = numberOrTriple(arg[0], sub + " lo");
    k.hi = numberOrTriple(arg[1], sub + " hi");
    if (k.lo.size() != k.hi.size())
      fail(arg.Mark(), sub + ": lo and hi must both be numbers or both lists of 3");
    for (std::size_t i = 0; i < k.lo.size(); ++i) {
      if (k.lo[i] > k.hi[i])
        fail(arg.Mark(),
             sub + ": lo " + numberText(k.lo[i]) + " is above hi " + numberText(k.hi[i]));
      if (!std::isfinite(k.hi[i] - k.lo[i]))  // a draw would be inf
        fail(arg.Mark(), sub + ": hi - lo must be a finite number, got " + numberText(k.lo[i]) +
                             " to " + numberText(k.hi[i]));
      if (k.draw == DrawKind::Integer &&
          (k.lo[i] != std::floor(k.lo[i]) || k.hi[i] != std::floor(k.hi[i]) ||
           std::fabs(k.lo[i]) > 9e15 || std::fabs(k.hi[i]) > 9e15))
        fail(arg.Mark(), sub + ": expected whole numbers");
    }
    if (k.key == kPathOffset && k.lo.size() != 3)
      fail(arg.Mark(), sub + ": path.offset_m draws [dx, dy, dz]: lo and hi are lists of 3");
    if ((k.key == kPathAngle || k.key == kPathSpeed) && k.lo.size() != 1)
      fail(arg.Mark(), sub + ": " + k.key + " is a number, not a list");
    if (k.key == kPathSpeed && !(k.lo[0] > 0))
      fail(arg.Mark(), sub + ": path.speed is a factor above 0");
  }

  void readRandom(const YAML::Node& n, SweepSpec& spec) const {
    if (n.IsNull()) return;
    if (!n.IsMap())
      fail(n.Mark(),
           "random: expected a mapping of scenario keys to distributions, got " + describe(n));
    for (const auto& kv : n) {
      checkKey(kv.first, "random");
      SweepKnob k;
      k.key = kv.first.Scalar();
      k.where = at(kv.first.Mark());
      k.source = KnobSource::Random;
      readDraw(kv.first, kv.second, k);
      spec.knobs.push_back(k);
    }
  }

  void readRunOptions(const YAML::Node& n, SweepSpec& spec) const {
    spec.runOptionsWhere = at(n.Mark());
    if (n.IsNull()) return;
    if (!n.IsSequence())
      fail(n.Mark(), "run_options: expected a list of `esim run` options, e.g. [--labels], got " +
                         describe(n));
    for (const auto& o : n) {
      if (!o.IsScalar())
        fail(o.Mark(), "run_options: expected options as text, got a " + describe(o));
      const std::string s = o.Scalar();
      if (const std::string why = sweepOwnedRunOption(s); !why.empty())
        fail(o.Mark(), "run_options: " + why);
      spec.runOptions.push_back(s);
    }
  }

  SweepSpec read(const std::string& text) {
    requireUtf8Text(text, file_, true);  // (its name and values go to the JSON manifest)
    YAML::Node root;
    try {
      root = YAML::Load(text);
    } catch (const YAML::ParserException& e) {
      fail(e.mark, "malformed YAML: " + printableInMessage(e.msg));
    }
    if (!root.IsMap())
      throw Error(file_ +
                  ": a sweep file is a mapping with base: and set:, grid: or random: "
                  "(scenarios/sweeps/README.md)");
    SweepSpec spec;
    spec.file = file_;
    spec.text = text;
    spec.name = fs::path(file_).stem().string();
    const std::vector<std::string> keys{"name", "description", "base",   "seed",       "draws",
                                        "set",  "grid",        "random", "run_options"};
    std::set<std::string> seen;
    YAML::Node drawsNode;
    for (const auto& kv : root) {
      const std::string key = kv.first.IsScalar() ? kv.first.Scalar() : "";
      if (std::find(keys.begin(), keys.end(), key) == keys.end()) {
        // a scenario given where a sweep file was expected (esim sweep scenarios/x.yaml)
        if (isScenarioKeyOrGroup(key) && !root["base"])
          fail(kv.first.Mark(),
               key +
                   ": a scenario key at the top of a sweep file: this looks like a scenario, "
                   "not a sweep file. A sweep file names its scenario in 'base:' and what to "
                   "vary in 'grid:' or 'random:' (scenarios/sweeps/README.md); a scenario "
                   "runs with esim run");
        const std::string near = closest(key, keys);
        fail(kv.first.Mark(), nameInMessage(key) + ": unknown key" +
                                  (near.empty() ? "; expected one of " + joined(keys)
                                                : "; did you mean '" + near + "'?"));
      }
      if (!seen.insert(key).second) fail(kv.first.Mark(), nameInMessage(key) + ": duplicate key");
      const YAML::Node& v = kv.second;
      if (key == "name" || key == "description") {
        if (!v.IsScalar()) fail(v.Mark(), key + ": expected text, got " + describe(v));
        if (const std::string problem = decodedTextProblem(v.Scalar()); !problem.empty())
          fail(v.Mark(), key + ": " + problem);
        (key == "name" ? spec.name : spec.description) = v.Scalar();
      } else if (key == "base") {
        if (!v.IsScalar() || v.Scalar().empty())
          fail(kv.first.Mark(), "base: expected the scenario file to vary, got " + describe(v));
        spec.baseWhere = at(v.Mark());
        const fs::path p(v.Scalar());
        const fs::path full = p.is_absolute() ? p : fs::path(file_).parent_path() / p;
        std::error_code ec;
        if (!fs::is_regular_file(full, ec))
          fail(v.Mark(), "base: " + printableInMessage(full.string()) +
                             ": no such scenario file (relative paths are from the sweep "
                             "file's folder)");
        spec.base = full.lexically_normal().string();
      } else if (key == "seed") {
        std::uint64_t s = 0;
        if (!v.IsScalar() || !YAML::convert<std::uint64_t>::decode(v, s) ||
            v.Scalar().find_first_not_of("0123456789") != std::string::npos)
          fail(v.Mark(), "seed: expected a whole number >= 0, got " + describe(v));
        spec.seed = s;
      } else if (key == "draws") {
        drawsNode = v;
        int d = 0;
        if (!v.IsScalar() || !YAML::convert<int>::decode(v, d) || d < 1 || d > 1000000)
          fail(v.Mark(), "draws: expected a whole number in [1, 1000000], got " + describe(v));
        spec.draws = d;
      } else if (key == "set") {
        readSet(v, spec);
      } else if (key == "grid") {
        readGrid(v, spec);
      } else if (key == "random") {
        readRandom(v, spec);
      } else if (key == "run_options") {
        readRunOptions(v, spec);
      }
    }
    if (spec.base.empty())
      throw Error(file_ +
                  ": base: missing: the scenario file to vary, e.g. base: ../slab_cut.yaml");
    // a key set twice would make its value ambiguous
    std::map<std::string, std::string> firstWhere;
    bool anyRandom = false;
    for (const auto& k : spec.knobs) {
      anyRandom = anyRandom || k.source == KnobSource::Random;
      const auto [it, fresh] = firstWhere.emplace(k.key, k.where);
      // jitter may go around a set or gridded value; anything else twice is ambiguous
      if (!fresh && !(k.source == KnobSource::Random && k.draw == DrawKind::Jitter))
        throw Error(k.where + ": " + k.key + ": also given at " + it->second +
                    "; a key is set, gridded or drawn once (jitter may go around a set or "
                    "gridded value)");
    }
    if (spec.draws > 1 && !anyRandom)
      fail(drawsNode.Mark(), "draws: " + std::to_string(spec.draws) +
                                 " draws without random: keys would make identical variants");
    if (sweepVariantCount(spec) > kMaxVariants)
      throw Error(file_ + ": the sweep makes " + std::to_string(sweepVariantCount(spec)) +
                  " variants, more than " + std::to_string(kMaxVariants) +
                  "; split it into several sweeps");
    return spec;
  }

 private:
  std::string file_;
};

// ---- expansion ----

// the value of a key in a loaded scenario, as YAML (for jitter's base value)
YAML::Node scenarioValue(const Scenario& s, const std::string& key) {
  YAML::Node node = YAML::Load(scenarioToYaml(s));
  std::stringstream ss(key);
  for (std::string part; std::getline(ss, part, '.');) node = node[part];
  return node;
}

struct PathTransform {
  Vec3 offset{0, 0, 0};
  double angleDeg = 0, speed = 1;
  std::string where;  // of the last path knob given
  bool any = false;
};

// nanometres and nano-degrees: transformed values read the same on every machine
double roundNano(double v) { return std::round(v * 1e9) / 1e9; }

Vec3 turnAbout(const Vec3& p, const Vec3& pivot, double angleDeg, const Vec3& offset) {
  const double a = angleDeg * M_PI / 180.0, c = std::cos(a), s = std::sin(a);
  const Vec3 d = p - pivot;
  const Vec3 q(pivot.x() + c * d.x() - s * d.y() + offset.x(),
               pivot.y() + s * d.x() + c * d.y() + offset.y(), p.z() + offset.z());
  return {roundNano(q.x()), roundNano(q.y()), roundNano(q.z())};
}

// the overrides that apply the path transforms to the loaded scenario
std::vector<std::string> pathOverrides(const Scenario& s, const PathTransform& t) {
  const auto& keys = s.tool.path;
  const Vec3 pivot = 0.5 * (keys.front().positionM + keys.back().positionM);
  std::string path = "tool.path=[";
  for (std::size_t i = 0; i < keys.size(); ++i) {
    const ScenarioKeyframe& k = keys[i];
    Vec3 o = k.orientationDeg;
    o.z() = roundNano(o.z() + t.angleDeg);
    path += std::string(i ? ", " : "") + "{t_s: " + numberText(roundNano(k.timeS / t.speed)) +
            ", position_m: " + vec3Text(turnAbout(k.positionM, pivot, t.angleDeg, t.offset)) +
            ", orientation_deg: " + vec3Text(o) + "}";
  }
  std::vector<std::string> out{path + "]"};
  if (s.mesh.source == MeshSource::Slab && s.mesh.slab.grading.enabled) {
    const auto& g = s.mesh.slab.grading;
    out.push_back("mesh.slab.grading.from_m=" +
                  vec3Text(turnAbout(g.fromM, pivot, t.angleDeg, t.offset)));
    out.push_back("mesh.slab.grading.to_m=" +
                  vec3Text(turnAbout(g.toM, pivot, t.angleDeg, t.offset)));
  }
  if (s.mesh.source == MeshSource::File && s.mesh.file.refine.enabled) {
    const auto& r = s.mesh.file.refine;
    out.push_back("mesh.file.refine.from_m=" +
                  vec3Text(turnAbout(r.fromM, pivot, t.angleDeg, t.offset)));
    out.push_back("mesh.file.refine.to_m=" +
                  vec3Text(turnAbout(r.toM, pivot, t.angleDeg, t.offset)));
  }
  return out;
}

// the numbers of a path transform's value (YAML text); throws Error naming `where` and the
// key where they are not finite numbers (a draw over [-1e308, 1e308] gave "inf", which
// yaml-cpp could not convert: an internal error)
std::vector<double> pathNumbers(const std::string& yaml, const std::string& where,
                                const std::string& key) {
  std::vector<double> v;
  try {
    const YAML::Node n = YAML::Load(yaml);
    if (n.IsSequence())
      v = {n[0].as<double>(), n[1].as<double>(), n[2].as<double>()};
    else
      v = {n.as<double>()};
  } catch (const YAML::Exception&) {
    v.clear();
  }
  if (v.empty() || !std::all_of(v.begin(), v.end(), [](double x) { return std::isfinite(x); }))
    throw Error(where + ": " + key + ": expected finite numbers, got " + yaml);
  return v;
}

void setPathKnob(PathTransform& t, const std::string& key, const std::vector<double>& v,
                 const std::string& where) {
  if (key == kPathOffset) t.offset = Vec3(v.at(0), v.at(1), v.at(2));
  if (key == kPathAngle) t.angleDeg = v.at(0);
  if (key == kPathSpeed) t.speed = v.at(0);
  t.where = where;
  t.any = true;
}

class Expander {
 public:
  explicit Expander(const SweepSpec& spec) : spec_(spec) {
    std::ifstream in(spec.base, std::ios::binary);
    if (!in)
      throw Error(spec.baseWhere + ": " + printableInMessage(spec.base) +
                  ": cannot open the scenario file");
    baseText_ = readYamlText(in, spec.baseWhere + ": " + spec.base, "scenario");
    for (const auto& k : spec.knobs)
      if (k.source == KnobSource::Grid) grid_.push_back(&k);
  }

  SweepVariant variant(std::size_t index, std::size_t count, bool withMesh) {
    SweepVariant v;
    v.index = static_cast<int>(index);
    v.id = variantId(index, count);
    v.values = nlohmann::json::object();
    wheres_.clear();
    // the grid point: the first key slowest
    std::size_t g = index / static_cast<std::size_t>(spec_.draws);
    std::vector<std::size_t> pick(grid_.size());
    for (std::size_t i = grid_.size(); i-- > 0;) {
      pick[i] = g % grid_[i]->values.size();
      g /= grid_[i]->values.size();
    }
    PathTransform path;
    for (const auto& k : spec_.knobs) {
      if (k.source == KnobSource::Set) add(v, path, k, k.values[0], k.valueWhere[0], false);
    }
    for (std::size_t i = 0; i < grid_.size(); ++i)
      add(v, path, *grid_[i], grid_[i]->values[pick[i]], grid_[i]->valueWhere[pick[i]], true);
    const std::vector<std::string> fixed = v.overrides;  // set and grid: jitter's base
    std::mt19937_64 engine = variantEngine(spec_.seed, index);
    std::optional<Scenario> before;  // the scenario before the draws (jitter's base values)
    for (const auto& k : spec_.knobs) {
      if (k.source != KnobSource::Random) continue;
      const std::string where = k.valueWhere.empty() ? k.where : k.valueWhere[0];
      switch (k.draw) {
        case DrawKind::Choice: {
          const std::size_t c = drawBelow(engine, k.values.size());
          add(v, path, k, k.values[c], k.valueWhere[c], true);
          break;
        }
        case DrawKind::Uniform:
        case DrawKind::Integer: {
          std::vector<double> x(k.lo.size());
          for (std::size_t i = 0; i < x.size(); ++i) {
            if (k.draw == DrawKind::Uniform) {
              x[i] = roundDrawn(k.lo[i] + (k.hi[i] - k.lo[i]) * drawUnit(engine));
            } else {
              const auto span = static_cast<std::uint64_t>(k.hi[i] - k.lo[i]) + 1;
              x[i] = k.lo[i] + static_cast<double>(drawBelow(engine, span));
            }
          }
          add(v, path, k, x.size() == 1 ? numberText(x[0]) : vectorText(x), where, true);
          break;
        }
        case DrawKind::Jitter: {
          std::vector<double> base;
          if (isPathKnob(k.key)) {
            base = k.key == kPathOffset ? std::vector<double>{0, 0, 0}
                                        : std::vector<double>{k.key == kPathSpeed ? 1.0 : 0.0};
          } else {
            if (!before) before = load(v, fixed, spec_.baseWhere);
            const YAML::Node b = scenarioValue(*before, k.key);
            try {
              if (b.IsSequence())
                for (const auto& c : b) base.push_back(c.as<double>());
              else
                base.push_back(b.as<double>());
            } catch (const YAML::Exception&) {
              throw Error(k.where + ": random." + k.key + ": jitter needs a number or a vector; " +
                          k.key + " is " + flowText(b));
            }
          }
          std::vector<double> h = k.hi;
          if (h.size() == 1 && base.size() == 3) h.assign(3, h[0]);
          if (h.size() != base.size())
            throw Error(where + ": random." + k.key + ".jitter: " + k.key + " is " +
                        (base.size() == 1 ? "a number: give one half-width"
                                          : "a vector: give a number or [dx, dy, dz]"));
          std::vector<double> x(base.size());
          for (std::size_t i = 0; i < x.size(); ++i)
            x[i] = roundDrawn(base[i] + h[i] * (2.0 * drawUnit(engine) - 1.0));
          add(v, path, k, x.size() == 1 ? numberText(x[0]) : vectorText(x), where, true);
          break;
        }
        case DrawKind::None:
          break;
      }
    }
    Scenario s = load(v, v.overrides, spec_.baseWhere);
    if (path.any) {
      for (const auto& o : pathOverrides(s, path)) {
        v.overrides.push_back(o);
        wheres_.push_back({o, path.where, "path"});
      }
      s = load(v, v.overrides, path.where);
    }
    try {
      checkRunnable(s, withMesh);
    } catch (const Error& e) {
      throw Error(spec_.file + ": variant " + v.id + " " + valuesText(v) + ": " + e.what(),
                  e.kind());
    }
    v.scenario = std::move(s);
    return v;
  }

 private:
  struct Origin {
    std::string override, where, key;
  };

  void add(SweepVariant& v, PathTransform& path, const SweepKnob& k, const std::string& value,
           const std::string& where, bool record) {
    if (record) v.values[k.key] = toJson(YAML::Load(value));
    if (isPathKnob(k.key)) {
      setPathKnob(path, k.key, pathNumbers(value, where, k.key), where);
      return;
    }
    const std::string o = k.key + "=" + value;
    v.overrides.push_back(o);
    wheres_.push_back({o, where, k.key});
  }

  static std::string valuesText(const SweepVariant& v) {
    return v.values.empty() ? std::string("(no values)") : jsonText(v.values);
  }

  // the base scenario with the variant's overrides so far; an error names the sweep
  // file's line of the value it comes from (or fallback), the key and the variant
  Scenario load(const SweepVariant& v, const std::vector<std::string>& overrides,
                const std::string& fallback) const {
    try {
      return parseScenario(baseText_, spec_.base, overrides);
    } catch (const Error& e) {
      const std::string msg = e.what();
      for (auto it = wheres_.rbegin(); it != wheres_.rend(); ++it)
        if (msg.find("--set " + nameInMessage(it->override) + ":") != std::string::npos)
          throw Error(
              it->where + ": " + it->key + ": variant " + v.id + " " + valuesText(v) + ": " + msg,
              e.kind());
      throw Error(fallback + ": variant " + v.id + " " + valuesText(v) + ": " + msg, e.kind());
    }
  }

  const SweepSpec& spec_;
  std::string baseText_;
  std::vector<const SweepKnob*> grid_;
  std::vector<Origin> wheres_;
};

}  // namespace

// ---- public ----

SweepSpec parseSweepSpec(const std::string& text, const std::string& sourceName) {
  try {
    return SpecReader(sourceName).read(text);
  } catch (const YAML::Exception& e) {  // defensive: yaml-cpp errors not caught above
    throw Error(where(sourceName, e.mark) + ": " + printableInMessage(e.msg));
  }
}

std::string sweepOwnedRunOption(const std::string& s) {
  for (const char* own : {"-o", "--out", "--overwrite", "-q", "--quiet"})
    if (s == own || s.rfind(std::string(own) + "=", 0) == 0 ||
        (std::string(own) == "-o" && s.rfind("-o", 0) == 0 && s.size() > 2 && s[2] != '-') ||
        (std::string(own) == "-q" && s.rfind("-q", 0) == 0 && s.size() > 2 && s[2] != '-'))
      return s + " is the sweep's to give (each run goes to DIR/runs/<id>/run, quiet)";
  if (s == "--set" || s.rfind("--set=", 0) == 0)
    return "--set: put the key under set: (it is then checked and recorded)";
  return "";
}

SweepSpec loadSweepSpec(const std::string& path) {
  std::error_code ec;
  if (fs::is_directory(path, ec))
    throw Error(path + ": is a folder; expected a sweep file (YAML, e.g. scenarios/sweeps/*.yaml)");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(path + ": cannot open the sweep file");
  return parseSweepSpec(readYamlText(in, path, "sweep"), path);
}

std::size_t sweepVariantCount(const SweepSpec& spec) {
  std::size_t n = static_cast<std::size_t>(spec.draws);
  for (const auto& k : spec.knobs)
    if (k.source == KnobSource::Grid) {
      n *= k.values.size();
      if (n > kMaxVariants * 1000) return n;  // no overflow
    }
  return n;
}

std::string variantId(std::size_t index, std::size_t count) {
  const int digits =
      std::max<int>(4, static_cast<int>(std::to_string(count ? count - 1 : 0).size()));
  const std::string n = std::to_string(index);
  std::string id = "v";
  id.append(n.size() < static_cast<std::size_t>(digits) ? digits - n.size() : 0, '0');
  id += n;
  return id;
}

std::vector<SweepVariant> expandSweep(const SweepSpec& spec, bool withMesh) {
  Expander ex(spec);
  const std::size_t n = sweepVariantCount(spec);
  std::vector<SweepVariant> out;
  out.reserve(n);
  for (std::size_t i = 0; i < n; ++i) out.push_back(ex.variant(i, n, withMesh));
  return out;
}

std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

std::mt19937_64 variantEngine(std::uint64_t seed, std::uint64_t index) {
  return std::mt19937_64(splitmix64(splitmix64(seed) + index));
}

double drawUnit(std::mt19937_64& engine) { return static_cast<double>(engine() >> 11) * 0x1.0p-53; }

std::uint64_t drawBelow(std::mt19937_64& engine, std::uint64_t n) {
  if (n <= 1) return 0;
  // the outputs below 2^64 mod n are rejected, so every residue is equally likely
  const std::uint64_t threshold = (0 - n) % n;
  for (;;) {
    const std::uint64_t x = engine();
    if (x >= threshold) return x % n;
  }
}

double roundDrawn(double v) {
  if (v == 0 || !std::isfinite(v)) return v;
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return std::strtod(buf, nullptr);
}

}  // namespace esim::app
