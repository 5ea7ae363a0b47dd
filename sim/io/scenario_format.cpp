// scenario_format.cpp - scenario values as YAML text (see scenario_format.h).
//
// Doubles in their shortest round-trip form (std::to_chars), plain decimals for
// everyday magnitudes and .inf/.nan as YAML spells them; strings double-quoted with
// escapes; vectors, keyframes, phase lists and intervals in flow style. The same text
// serves the resolved scenario (scenarioToYaml, and so scenarioHash), the reference
// table and the numbers quoted in error messages.
#include "sim/io/scenario_format.h"

#include <charconv>
#include <cmath>
#include <cstdio>

namespace esim::scenario_detail {

namespace {

std::string quoteString(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\t':
        out += "\\t";
        break;
      case '\r':
        out += "\\r";
        break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          char b[8];
          std::snprintf(b, sizeof(b), "\\x%02x", static_cast<unsigned char>(c));
          out += b;
        } else {
          out += c;
        }
    }
  }
  return out + "\"";
}

// a range bound: the shortest form (1e+08 rather than 100000000)
std::string formatBound(double v) {
  if (std::isinf(v)) return v > 0 ? ".inf" : "-.inf";
  char buf[64];
  auto res = std::to_chars(buf, buf + sizeof(buf), v);
  return std::string(buf, res.ptr);
}

}  // namespace

// shortest text that reads back to the same double; .inf for infinity
std::string formatNumber(double v) {
  if (std::isinf(v)) return v > 0 ? ".inf" : "-.inf";
  if (std::isnan(v)) return ".nan";
  // shortest round-trip digits; plain decimals for everyday magnitudes (0.0005, 3820000)
  const double mag = std::abs(v);
  const bool fixed = mag == 0.0 || (mag >= 1e-5 && mag < 1e9);
  char buf[400];
  auto res = std::to_chars(buf, buf + sizeof(buf), v,
                           fixed ? std::chars_format::fixed : std::chars_format::scientific);
  return std::string(buf, res.ptr);
}

std::string formatVector(const Vec3& v) {
  std::string out = "[";
  for (int i = 0; i < 3; ++i) {
    if (i > 0) out += ", ";
    out += formatNumber(v[i]);
  }
  return out + "]";
}

std::string formatKeyframe(const ScenarioKeyframe& k) {
  return "{t_s: " + formatNumber(k.timeS) + ", position_m: " + formatVector(k.positionM) +
         ", orientation_deg: " + formatVector(k.orientationDeg) + "}";
}

// the value of a field as (flow) YAML text
std::string formatValue(const Field& f, const Scenario& constScenario) {
  // the refs take a mutable Scenario; nothing is written through them here
  Scenario& s = const_cast<Scenario&>(constScenario);
  switch (f.kind) {
    case Kind::Number:
      return formatNumber(std::get<NumberRef>(f.ref)(s));
    case Kind::Integer:
      return std::to_string(std::get<IntRef>(f.ref)(s));
    case Kind::Bool:
      return std::get<BoolRef>(f.ref)(s) ? "true" : "false";
    case Kind::Choice:
      return choiceText(f, s);
    case Kind::Text:
      return quoteString(std::get<StringRef>(f.ref)(s));
    case Kind::Vector:
      return formatVector(std::get<VecRef>(f.ref)(s));
    case Kind::IntTriple: {
      // appended piecewise: "[" + std::to_string(...) trips a false -Wrestrict in GCC 12
      const auto& a = std::get<Int3Ref>(f.ref)(s);
      std::string out = "[";
      for (int i = 0; i < 3; ++i) {
        if (i > 0) out += ", ";
        out += std::to_string(a[i]);
      }
      return out + "]";
    }
    case Kind::Phases: {
      std::string out = "[";
      for (Phase p : std::get<PhasesRef>(f.ref)(s))
        out += (out.size() > 1 ? ", " : "") + std::string(phaseName(p));
      return out + "]";
    }
    case Kind::Keyframes: {
      std::string out = "[";
      for (const auto& k : std::get<KeysRef>(f.ref)(s))
        out += (out.size() > 1 ? ", " : "") + formatKeyframe(k);
      return out + "]";
    }
    case Kind::Intervals: {
      std::string out = "[";
      for (const auto& iv : std::get<IntervalsRef>(f.ref)(s))
        out += (out.size() > 1 ? ", " : "") + std::string("[") + formatNumber(iv[0]) + ", " +
               formatNumber(iv[1]) + "]";
      return out + "]";
    }
  }
  return "";
}

std::string formatRange(const Range& r) {
  return std::string(r.loOpen ? "(" : "[") + formatBound(r.lo) + ", " + formatBound(r.hi) +
         (r.hiOpen ? ")" : "]");
}

std::string joinList(const std::vector<std::string>& items) {
  std::string out;
  for (const auto& s : items) out += (out.empty() ? "" : ", ") + s;
  return out;
}

}  // namespace esim::scenario_detail
