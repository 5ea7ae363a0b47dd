// scenario_reader.cpp - YAML tree -> Scenario with located errors and suggestions.
//
// Reader (scenario_reader.h) walks each mapping against the schema: unknown keys,
// duplicate keys, wrong types and out-of-range values are errors that name the file,
// line and column (or the --set override the value came from) and suggest the closest
// key or choice within a typo's edit distance. Phase lists, tool keyframes and generator
// intervals have their own readers. applyOverride merges "--set key.path=value" into
// the YAML tree before reading.
#include "sim/io/scenario_reader.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <sstream>

#include "sim/core_error.h"
#include "sim/io/scenario.h"
#include "sim/io/scenario_format.h"
#include "sim/message_text.h"

namespace esim::scenario_detail {

namespace {

// "in metres" etc. for messages
std::string unitPhrase(const std::string& unit) {
  static const std::map<std::string, std::string> words{
      {"m", "metres"},    {"s", "seconds"},         {"V", "volts"},   {"Pa", "pascals"},
      {"deg", "degrees"}, {"C", "degrees Celsius"}, {"px", "pixels"}, {"MB", "megabytes"}};
  if (unit.empty()) return "";
  auto it = words.find(unit);
  return " in " + (it != words.end() ? it->second : unit);
}

// ---- suggestions ----

size_t editDistance(const std::string& a, const std::string& b) {
  std::vector<size_t> row(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    size_t diag = row[0];
    row[0] = i;
    for (size_t j = 1; j <= b.size(); ++j) {
      const size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diag + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diag = up;
    }
  }
  return row[b.size()];
}

// the closest candidate within a typo's distance ("" if none); a candidate that extends
// the word (missing unit suffix, e.g. voltage -> voltage_v) also counts
std::string closestName(const std::string& word, const std::vector<std::string>& candidates) {
  std::string best;
  size_t bestDist = std::max<size_t>(2, word.size() / 3) + 1;
  for (const auto& c : candidates) {
    size_t d = editDistance(word, c);
    if (word.size() >= 3 && c.compare(0, word.size(), word) == 0) d = std::min<size_t>(d, 1);
    if (d < bestDist) {
      bestDist = d;
      best = c;
    }
  }
  return best;
}

}  // namespace

// ---- Reader ----

// where a field's value came from: "--set k=v", "file:line:col" or "file"
namespace {

// is `path` the override's key or a field under it?
bool underKey(const std::string& path, const std::string& key) {
  return path == key || (path.size() > key.size() && path.compare(0, key.size(), key) == 0 &&
                         (path[key.size()] == '.' || path[key.size()] == '['));
}

}  // namespace

bool Reader::fromOverride(const std::string& path) const {
  for (const auto& [key, text] : overrides_)
    if (underKey(path, key)) return true;
  return false;
}

std::string Reader::where(const std::string& path, const YAML::Mark& mark) const {
  for (const auto& [key, text] : overrides_)
    if (underKey(path, key)) return source_ + ": --set " + nameInMessage(text);
  if (mark.is_null()) return source_;
  return source_ + ":" + std::to_string(mark.line + 1) + ":" + std::to_string(mark.column + 1);
}
std::string Reader::where(const std::string& path) const {
  auto it = marks_.find(path);
  return where(path, it != marks_.end() ? it->second : YAML::Mark::null_mark());
}

void Reader::fail(const std::string& path, const YAML::Mark& mark,
                  const std::string& message) const {
  throw Error(where(path, mark) + ": " + message);
}
void Reader::fail(const std::string& path, const std::string& message) const {
  throw Error(where(path) + ": " + message);
}

// reads a mapping (the root or a group) into s
void Reader::readGroup(const YAML::Node& node, const std::string& group, Scenario& s) {
  if (node.IsNull()) return;  // "effects:" with nothing under it keeps the defaults
  if (!node.IsMap())
    fail(group, node.Mark(),
         (group.empty() ? std::string("the scenario") : group) + ": expected a mapping with keys " +
             joinList(childKeys(group)) + ", got " + describe(node));
  std::set<std::string> seen;
  for (auto it = node.begin(); it != node.end(); ++it) {
    // copies: the iterator's -> yields a temporary proxy (nodes are shared handles)
    const YAML::Node keyNode = it->first;
    const YAML::Node value = it->second;
    if (!keyNode.IsScalar())
      fail(group, keyNode.Mark(),
           (group.empty() ? std::string("scenario") : group) + ": keys must be plain names");
    const std::string key = keyNode.Scalar();
    const std::string path = joinPath(group, key);
    if (!seen.insert(key).second)
      fail(path, keyNode.Mark(), nameInMessage(path) + ": duplicate key");
    const YAML::Mark mark = markOf(value, keyNode);
    marks_[path] = mark;
    if (const Field* f = findField(path)) {
      readField(*f, value, path, mark, s);
    } else if (isGroup(path)) {
      readGroup(value, path, s);
    } else {
      fail(path, keyNode.Mark(), unknownKeyMessage(group, key));
    }
  }
}

std::string Reader::unknownKeyMessage(const std::string& group, const std::string& key) {
  const std::string full = joinPath(group, key), path = nameInMessage(full);
  const std::vector<std::string> siblings = childKeys(group);
  const std::string near = closestName(key, siblings);
  if (!near.empty()) return path + ": unknown key; did you mean '" + near + "'?";
  // the same key in another section?
  for (const Field& f : schema()) {
    const std::string leaf = f.path.substr(f.path.rfind('.') + 1);
    if (leaf == key && f.path != full)
      return path + ": unknown key; did you mean '" + f.path + "'?";
  }
  return path + ": unknown key; expected one of " + joinList(siblings);
}

std::string Reader::describe(const YAML::Node& n) {
  if (!n.IsDefined() || n.IsNull()) return "nothing";
  if (n.IsSequence()) return "a list";
  if (n.IsMap()) return "a mapping";
  return quoteInMessage(n.Scalar());
}

// a null value has no useful mark: point at its key
YAML::Mark Reader::markOf(const YAML::Node& value, const YAML::Node& key) {
  if (value.IsNull() || value.Mark().is_null()) return key.Mark();
  return value.Mark();
}

double Reader::readNumber(const YAML::Node& n, const std::string& path, const YAML::Mark& mark,
                          const std::string& unit, const Range& range) const {
  double v = 0;
  if (!n.IsScalar() || !YAML::convert<double>::decode(n, v) || std::isnan(v))
    fail(path, mark, path + ": expected a number" + unitPhrase(unit) + ", got " + describe(n));
  if (!range.contains(v))
    fail(path, mark, path + " = " + formatNumber(v) + " is outside " + formatRange(range));
  return v;
}

int Reader::readInteger(const YAML::Node& n, const std::string& path, const YAML::Mark& mark,
                        const std::string& unit, const Range& range) const {
  double v = 0;
  if (!n.IsScalar() || !YAML::convert<double>::decode(n, v) || !std::isfinite(v) ||
      v != std::floor(v))
    fail(path, mark, path + ": expected an integer" + unitPhrase(unit) + ", got " + describe(n));
  if (!range.contains(v))
    fail(path, mark, path + " = " + formatNumber(v) + " is outside " + formatRange(range));
  return static_cast<int>(v);
}

Vec3 Reader::readVector(const YAML::Node& n, const std::string& path, const YAML::Mark& mark,
                        const std::string& unit, const Range& range, bool nonzero) const {
  if (!n.IsSequence() || n.size() != 3)
    fail(path, mark,
         path + ": expected a list of 3 numbers" + unitPhrase(unit) + " [x, y, z], got " +
             (n.IsSequence() ? "a list of " + std::to_string(n.size()) : describe(n)));
  Vec3 v;
  for (int i = 0; i < 3; ++i) {
    const std::string item = path + "[" + std::to_string(i) + "]";
    v[i] = readNumber(n[i], item, n[i].Mark(), unit, range);
  }
  if (nonzero && v.norm() == 0.0) fail(path, mark, path + ": must not be the zero vector");
  return v;
}

std::string Reader::readScalarText(const YAML::Node& n, const std::string& path,
                                   const YAML::Mark& mark, const std::string& expected) const {
  if (n.IsNull()) return "";
  if (!n.IsScalar()) fail(path, mark, path + ": expected " + expected + ", got " + describe(n));
  // what its escapes decode to (decodedTextProblem); escaped control characters are text,
  // written back as escapes
  const std::string& v = n.Scalar();
  if (const std::string problem = decodedTextProblem(v); !problem.empty())
    fail(path, mark, path + ": " + problem);
  return v;
}

void Reader::readField(const Field& f, const YAML::Node& n, const std::string& path,
                       const YAML::Mark& mark, Scenario& s) {
  switch (f.kind) {
    case Kind::Number:
      std::get<NumberRef>(f.ref)(s) = readNumber(n, path, mark, f.unit, f.range);
      return;
    case Kind::Integer:
      std::get<IntRef>(f.ref)(s) = readInteger(n, path, mark, f.unit, f.range);
      return;
    case Kind::Bool: {
      bool b = false;
      if (!n.IsScalar() || !YAML::convert<bool>::decode(n, b))
        fail(path, mark, path + ": expected true or false, got " + describe(n));
      std::get<BoolRef>(f.ref)(s) = b;
      return;
    }
    case Kind::Choice: {
      const std::string v = n.IsScalar() ? n.Scalar() : "";
      if (!n.IsScalar() || std::find(f.choices.begin(), f.choices.end(), v) == f.choices.end()) {
        const std::string near = n.IsScalar() ? closestName(v, f.choices) : "";
        fail(path, mark,
             path + ": unknown value " + describe(n) +
                 (near.empty() ? "" : "; did you mean '" + near + "'?") + " expected one of " +
                 joinList(f.choices));
      }
      setChoice(f, s, v);
      return;
    }
    case Kind::Text:
      std::get<StringRef>(f.ref)(s) = readScalarText(n, path, mark, "a string");
      return;
    case Kind::Vector:
      std::get<VecRef>(f.ref)(s) = readVector(n, path, mark, f.unit, f.range, f.nonzero);
      return;
    case Kind::IntTriple: {
      if (!n.IsSequence() || n.size() != 3)
        fail(path, mark, path + ": expected a list of 3 integers, got " + describe(n));
      auto& a = std::get<Int3Ref>(f.ref)(s);
      for (int i = 0; i < 3; ++i)
        a[i] =
            readInteger(n[i], path + "[" + std::to_string(i) + "]", n[i].Mark(), f.unit, f.range);
      return;
    }
    case Kind::Phases:
      readPhases(f, n, path, mark, std::get<PhasesRef>(f.ref)(s));
      return;
    case Kind::Keyframes:
      readKeyframes(n, path, mark, std::get<KeysRef>(f.ref)(s));
      return;
    case Kind::Intervals:
      readIntervals(f, n, path, mark, std::get<IntervalsRef>(f.ref)(s));
      return;
  }
}

void Reader::readPhases(const Field& f, const YAML::Node& n, const std::string& path,
                        const YAML::Mark& mark, std::vector<Phase>& out) const {
  if (n.IsNull()) {
    out.clear();
    return;
  }
  if (!n.IsSequence())
    fail(path, mark,
         path + ": expected a list of phases [" + joinList(f.choices) + "], got " + describe(n));
  std::vector<Phase> phases;
  for (size_t i = 0; i < n.size(); ++i) {
    const std::string item = path + "[" + std::to_string(i) + "]";
    const std::string name = n[i].IsScalar() ? n[i].Scalar() : "";
    auto it = std::find(f.choices.begin(), f.choices.end(), name);
    if (it == f.choices.end()) {
      const std::string near = n[i].IsScalar() ? closestName(name, f.choices) : "";
      fail(item, n[i].Mark(),
           item + ": unknown phase " + describe(n[i]) +
               (near.empty() ? "" : "; did you mean '" + near + "'?") + " expected one of " +
               joinList(f.choices));
    }
    const Phase p = static_cast<Phase>(it - f.choices.begin());
    if (std::find(phases.begin(), phases.end(), p) != phases.end())
      fail(item, n[i].Mark(), item + ": phase '" + name + "' is listed twice");
    phases.push_back(p);
  }
  std::sort(phases.begin(), phases.end());
  out = phases;
}

void Reader::readKeyframes(const YAML::Node& n, const std::string& path, const YAML::Mark& mark,
                           std::vector<ScenarioKeyframe>& out) const {
  if (!n.IsSequence() || n.size() == 0)
    fail(path, mark,
         path +
             ": expected a list of at least one keyframe {t_s, position_m, "
             "orientation_deg}, got " +
             (n.IsSequence() ? std::string("an empty list") : describe(n)));
  std::vector<std::string> names;
  for (const auto& k : keyframeSchema()) names.push_back(k.name);
  std::vector<ScenarioKeyframe> keys;
  for (size_t i = 0; i < n.size(); ++i) {
    const std::string item = path + "[" + std::to_string(i) + "]";
    const YAML::Node& kn = n[i];
    if (!kn.IsMap())
      fail(item, kn.Mark(),
           item +
               ": expected a keyframe {t_s, position_m, orientation_deg}, "
               "got " +
               describe(kn));
    ScenarioKeyframe key;
    std::set<std::string> seen;
    YAML::Mark timeMark = kn.Mark();
    for (auto it = kn.begin(); it != kn.end(); ++it) {
      const YAML::Node keyNode = it->first, value = it->second;  // copies of the proxy
      const std::string name = keyNode.IsScalar() ? keyNode.Scalar() : "?";
      const std::string sub = item + "." + name;
      if (!seen.insert(name).second)
        fail(sub, keyNode.Mark(), nameInMessage(sub) + ": duplicate key");
      const YAML::Mark vm = markOf(value, keyNode);
      if (name == "t_s") {
        key.timeS = readNumber(value, sub, vm, "s", keyframeSchema()[0].range);
        timeMark = vm;
      } else if (name == "position_m") {
        key.positionM = readVector(value, sub, vm, "m", keyframeSchema()[1].range, false);
      } else if (name == "orientation_deg") {
        key.orientationDeg = readVector(value, sub, vm, "deg", keyframeSchema()[2].range, false);
      } else {
        const std::string near = closestName(name, names);
        fail(sub, keyNode.Mark(),
             nameInMessage(sub) + ": unknown key; " +
                 (near.empty() ? "expected one of " + joinList(names)
                               : "did you mean '" + near + "'?"));
      }
    }
    for (const auto& k : keyframeSchema())
      if (k.required && !seen.count(k.name))
        fail(item, kn.Mark(), item + ": missing '" + k.name + "' (" + k.description + ")");
    if (i > 0 && !(key.timeS > keys.back().timeS))
      fail(item + ".t_s", timeMark,
           item + ".t_s = " + formatNumber(key.timeS) + " is not after " + path + "[" +
               std::to_string(i - 1) + "].t_s = " + formatNumber(keys.back().timeS) +
               "; keyframe times must strictly increase");
    keys.push_back(key);
  }
  out = keys;
}

void Reader::readIntervals(const Field& f, const YAML::Node& n, const std::string& path,
                           const YAML::Mark& mark, std::vector<std::array<double, 2>>& out) const {
  if (n.IsNull()) {
    out.clear();
    return;
  }
  if (!n.IsSequence())
    fail(path, mark,
         path + ": expected a list of [on, off] intervals in seconds, got " + describe(n));
  std::vector<std::array<double, 2>> intervals;
  for (size_t i = 0; i < n.size(); ++i) {
    const std::string item = path + "[" + std::to_string(i) + "]";
    const YAML::Node& in = n[i];
    if (!in.IsSequence() || in.size() != 2)
      fail(item, in.Mark(), item + ": expected [on, off] in seconds, got " + describe(in));
    const double on = readNumber(in[0], item + "[0]", in[0].Mark(), "s", {0.0, kInf, false, true});
    const double off = readNumber(in[1], item + "[1]", in[1].Mark(), "s", f.range);
    if (!(off > on))
      fail(item, in.Mark(),
           item + ": off time " + formatNumber(off) + " s must be after on time " +
               formatNumber(on) + " s");
    if (!intervals.empty() && on < intervals.back()[1])
      fail(item, in.Mark(),
           item + ": starts at " + formatNumber(on) + " s, before the previous interval ends (" +
               formatNumber(intervals.back()[1]) + " s); intervals must be sorted and disjoint");
    intervals.push_back({on, off});
  }
  out = intervals;
}

// ---- overrides ----

// sets root[k1][k2]...[kn] = value, creating mappings on the way
void setPath(YAML::Node node, const std::vector<std::string>& keys, size_t i,
             const YAML::Node& value) {
  if (i + 1 == keys.size()) {
    node[keys[i]] = value;
    return;
  }
  YAML::Node child = node[keys[i]];
  if (!child.IsMap()) {
    node[keys[i]] = YAML::Node(YAML::NodeType::Map);
    child = node[keys[i]];
  }
  setPath(child, keys, i + 1, value);
}

void applyOverride(YAML::Node& root, const std::string& text, const std::string& source,
                   Reader& reader) {
  const std::string where = source + ": --set " + nameInMessage(text) + ": ";
  const size_t eq = text.find('=');
  if (eq == std::string::npos || eq == 0)
    throw Error(where + "expected key.path=value, e.g. tool.voltage_v=60");
  std::string key = text.substr(0, eq);
  key.erase(0, key.find_first_not_of(" \t"));
  key.erase(key.find_last_not_of(" \t") + 1);
  if (key.empty())
    throw Error(where + "the key is blank; expected key.path=value, e.g. tool.voltage_v=60");
  const std::string valueText = text.substr(eq + 1);
  // each step of the path must be a group, the last a field or a group
  std::vector<std::string> keys;
  std::string group;
  std::stringstream ss(key);
  for (std::string k; std::getline(ss, k, '.');) {
    const std::string path = joinPath(group, k);
    if (const size_t bracket = k.find('['); bracket != std::string::npos && bracket > 0)
      throw Error(where + nameInMessage(path) +
                  ": --set cannot pick one entry of a list; give the whole list (" +
                  nameInMessage(joinPath(group, k.substr(0, bracket))) +
                  "=[...], in YAML flow style) or edit the scenario file");
    if (k.empty() || (!findField(path) && !isGroup(path)))
      throw Error(where + Reader::unknownKeyMessage(group, k));
    if (findField(path) && path != key) throw Error(where + path + " is a value, not a group");
    keys.push_back(k);
    group = path;
  }
  YAML::Node value;
  try {
    value = YAML::Load(valueText);
  } catch (const YAML::Exception& e) {
    // {t_s:0} is one plain scalar "t_s:0" to YAML, and yaml-cpp then only says that the map
    // does not end
    bool tightColon = false;
    for (size_t i = valueText.find(':'); i != std::string::npos; i = valueText.find(':', i + 1))
      tightColon |= i + 1 < valueText.size() && valueText[i + 1] != ' ';
    throw Error(where + "malformed value: " + printableInMessage(e.msg) +
                (tightColon ? " (in YAML flow style each ':' is followed by a space: "
                              "[{t_s: 0, position_m: [0, 0, 0.01]}])"
                            : ""));
  }
  if (!root.IsMap()) root = YAML::Node(YAML::NodeType::Map);
  setPath(root, keys, 0, value);
  reader.noteOverride(key, text);
}

}  // namespace esim::scenario_detail
