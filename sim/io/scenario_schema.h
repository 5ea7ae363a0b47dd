// scenario_schema.h - internal to esim_io: the types of the scenario schema and its lookups.
//
// The schema is one table (scenario_schema.cpp) with a Field per YAML key: its key path,
// type (Kind), SI unit, allowed range or choices, description and a reference to the
// Scenario member it fills; the defaults are Scenario's member initializers. The reader
// (scenario_reader.cpp), the writer and reference (scenario_writer.cpp) and the value
// formatting (scenario_format.cpp) all walk this one table. Not part of the public API.
#pragma once

#include <array>
#include <cmath>
#include <limits>
#include <string>
#include <variant>
#include <vector>

#include "sim/io/scenario.h"

namespace esim::scenario_detail {

inline constexpr double kInf = std::numeric_limits<double>::infinity();

enum class Kind {
  Number,
  Integer,
  Bool,
  Choice,
  Text,
  Vector,
  IntTriple,
  Phases,
  Keyframes,
  Intervals
};

// an interval of allowed values; open ends exclude the bound
struct Range {
  double lo = -kInf, hi = kInf;
  bool loOpen = true, hiOpen = true;
  bool contains(double v) const {
    if (std::isnan(v)) return false;
    const bool okLo = loOpen ? v > lo : v >= lo;
    const bool okHi = hiOpen ? v < hi : v <= hi;
    return okLo && okHi;
  }
};

using NumberRef = double& (*)(Scenario&);
using IntRef = int& (*)(Scenario&);
using BoolRef = bool& (*)(Scenario&);
using StringRef = std::string& (*)(Scenario&);
using VecRef = Vec3& (*)(Scenario&);
using Int3Ref = std::array<int, 3>& (*)(Scenario&);
using PhasesRef = std::vector<Phase>& (*)(Scenario&);
using KeysRef = std::vector<ScenarioKeyframe>& (*)(Scenario&);
using IntervalsRef = std::vector<std::array<double, 2>>& (*)(Scenario&);
// a choice held as an enum: its value is the index of its name in Field::choices
struct EnumRef {
  int (*get)(const Scenario&);
  void (*set)(Scenario&, int);
};
using Ref = std::variant<NumberRef, IntRef, BoolRef, StringRef, VecRef, Int3Ref, PhasesRef, KeysRef,
                         IntervalsRef, EnumRef>;

struct Field {
  std::string path;  // YAML key path
  Kind kind;
  std::string unit;  // SI symbol, "" when dimensionless
  Range range;       // numbers, integers, each vector component, interval ends
  std::vector<std::string> choices;
  std::string description;
  Ref ref;
  bool nonzero = false;  // vectors that must not be zero (directions)
};

// the text of a choice field (a string member, or an enum's name)
std::string choiceText(const Field& field, const Scenario& scenario);
// sets a choice field from one of its names (checked by the caller)
void setChoice(const Field& field, Scenario& scenario, const std::string& name);

// keyframe sub-fields (entries of tool.path), used by the reader and the reference
struct KeyField {
  const char* name;
  Kind kind;  // Number or Vector
  const char* unit;
  Range range;
  bool required;
  const char* description;
};

// the schema: the single source of truth for keys, types, units, ranges and descriptions.
// Defaults are the member initializers of Scenario (scenario.h). Groups are contiguous.
const std::vector<Field>& schema();
// t_s, position_m, orientation_deg, in this order
const std::vector<KeyField>& keyframeSchema();

// the field at a key path, nullptr if none
const Field* findField(const std::string& path);
// true when path is a proper prefix group of some field ("" is the root)
bool isGroup(const std::string& path);
// immediate child keys of a group, in schema order
std::vector<std::string> childKeys(const std::string& group);
// "group.key", or "key" at the root
std::string joinPath(const std::string& group, const std::string& key);

}  // namespace esim::scenario_detail
