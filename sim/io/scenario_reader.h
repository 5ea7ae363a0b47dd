// scenario_reader.h - internal to esim_io: YAML tree -> Scenario, key by key.
//
// Reader walks a YAML mapping against the schema, checks each value's type and range
// and writes it into the Scenario; every error names where the value came from
// ("file:line:col", or "file: --set k=v" for an override) and suggests the closest key
// or choice for a typo. applyOverride merges one "--set key.path=value" into the tree
// before reading. Implemented in scenario_reader.cpp; the cross-field rules that run
// after reading are in scenario_checks.h.
#pragma once

#include <yaml-cpp/yaml.h>

#include <array>
#include <map>
#include <string>
#include <vector>

#include "sim/io/scenario_schema.h"

namespace esim::scenario_detail {

class Reader {
 public:
  explicit Reader(std::string source) : source_(std::move(source)) {}

  // remembers an override so messages about its fields point at it
  void noteOverride(const std::string& path, const std::string& text) { overrides_[path] = text; }

  // was this field (or a group above it) given by an override?
  bool fromOverride(const std::string& path) const;

  // where a field's value came from: "--set k=v", "file:line:col" or "file"
  std::string where(const std::string& path, const YAML::Mark& mark) const;
  std::string where(const std::string& path) const;

  [[noreturn]] void fail(const std::string& path, const YAML::Mark& mark,
                         const std::string& message) const;
  [[noreturn]] void fail(const std::string& path, const std::string& message) const;

  // reads a mapping (the root or a group) into s
  void readGroup(const YAML::Node& node, const std::string& group, Scenario& s);

  // "group.key: unknown key; did you mean ...?" (or the list of keys of the group)
  static std::string unknownKeyMessage(const std::string& group, const std::string& key);
  // "nothing", "a list", "a mapping" or the quoted scalar
  static std::string describe(const YAML::Node& n);

  const std::map<std::string, YAML::Mark>& marks() const { return marks_; }

 private:
  // a null value has no useful mark: point at its key
  static YAML::Mark markOf(const YAML::Node& value, const YAML::Node& key);

  double readNumber(const YAML::Node& n, const std::string& path, const YAML::Mark& mark,
                    const std::string& unit, const Range& range) const;
  int readInteger(const YAML::Node& n, const std::string& path, const YAML::Mark& mark,
                  const std::string& unit, const Range& range) const;
  Vec3 readVector(const YAML::Node& n, const std::string& path, const YAML::Mark& mark,
                  const std::string& unit, const Range& range, bool nonzero) const;
  std::string readScalarText(const YAML::Node& n, const std::string& path, const YAML::Mark& mark,
                             const std::string& expected) const;
  void readField(const Field& f, const YAML::Node& n, const std::string& path,
                 const YAML::Mark& mark, Scenario& s);
  void readPhases(const Field& f, const YAML::Node& n, const std::string& path,
                  const YAML::Mark& mark, std::vector<Phase>& out) const;
  void readKeyframes(const YAML::Node& n, const std::string& path, const YAML::Mark& mark,
                     std::vector<ScenarioKeyframe>& out) const;
  void readIntervals(const Field& f, const YAML::Node& n, const std::string& path,
                     const YAML::Mark& mark, std::vector<std::array<double, 2>>& out) const;

  std::string source_;
  std::map<std::string, std::string> overrides_;
  std::map<std::string, YAML::Mark> marks_;
};

// merges "key.path=value" (value parsed as YAML) into root and notes it in reader;
// the key path must name schema groups and a field or group
void applyOverride(YAML::Node& root, const std::string& text, const std::string& source,
                   Reader& reader);

}  // namespace esim::scenario_detail
