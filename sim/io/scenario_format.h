// scenario_format.h - internal to esim_io: scenario values as YAML text.
//
// Numbers in their shortest round-trip form (plain decimals for everyday magnitudes,
// .inf for infinity), vectors and keyframes in flow style, any schema field's value,
// allowed ranges ("[a, b]", "(a, b]") and comma-separated lists. Used by the writer,
// the reference, and the reader's and checks' error messages (scenario_format.cpp).
#pragma once

#include <string>
#include <vector>

#include "sim/io/scenario_schema.h"

namespace esim::scenario_detail {

// shortest text that reads back to the same double; .inf for infinity
std::string formatNumber(double v);
std::string formatVector(const Vec3& v);
std::string formatKeyframe(const ScenarioKeyframe& k);
// the value of a field as (flow) YAML text
std::string formatValue(const Field& f, const Scenario& constScenario);
// "[lo, hi]" with "(" or ")" for open ends
std::string formatRange(const Range& r);
// "a, b, c"
std::string joinList(const std::vector<std::string>& items);

}  // namespace esim::scenario_detail
