// fuzz_scenario.cpp - libFuzzer target: the scenario loader on any text,
// parseScenario(text, "fuzz.yaml", {}), then the checks of scenario_oracle.h.
// Its finding, a text with NUL bytes that yaml-cpp read as UTF-16 or UTF-32 (the name it gave
// was not UTF-8, so the resolved scenario could not be read back), is fixed: requireUtf8Text
// refuses control characters; kept in tests/fuzz/fuzz_scenario/regression-nul-*.
#include <cstddef>
#include <cstdint>
#include <string>

#include "sim/io/scenario.h"
#include "tests/fuzz/fuzz_common.h"
#include "tests/fuzz/scenario_oracle.h"

using namespace esim;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  Scenario s;
  if (fuzz::accepts([&] { s = parseScenario(text, "fuzz.yaml", {}); }))
    fuzz::checkAcceptedScenario(s);
  return 0;
}
