// fuzz_override.cpp - libFuzzer target: one `--set key.path=value` override on a minimal
// scenario, parseScenario("name: x\n", "fuzz.yaml", {input}), then the checks of
// scenario_oracle.h.
// Its finding, an override whose key is blank (" =1") indexing an empty key list, is fixed
// (refused by applyOverride); the inputs are kept in tests/fuzz/fuzz_override/regression-*.
// So is its second, a value starting with NUL bytes, which yaml-cpp read as UTF-32 into a name
// that was no longer UTF-8 (refused by requireUtf8Text: no control characters in the text).
// And its third, a double-quoted "\N" (YAML's U+0085), which yaml-cpp decodes to the one byte
// 0x85, so the name was not UTF-8 and the resolved scenario could not be read back (refused:
// decodedTextProblem; regression-nel-escape-not-utf8).
#include <cstddef>
#include <cstdint>
#include <string>

#include "sim/io/scenario.h"
#include "tests/fuzz/fuzz_common.h"
#include "tests/fuzz/scenario_oracle.h"

using namespace esim;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string override(reinterpret_cast<const char*>(data), size);
  Scenario s;
  if (fuzz::accepts([&] { s = parseScenario("name: x\n", "fuzz.yaml", {override}); }))
    fuzz::checkAcceptedScenario(s);
  return 0;
}
