// scenario_oracle.h - what the scenario targets check on a scenario the loader accepted:
// the documented round trip parse(toYaml(s)) == s (sim/io/scenario.h), and that the
// runner's derived values (frame count, slab spec, meshing options, tool path, summary)
// come out of it without anything but an Input or Run error.
#pragma once

#include <string>

#include "sim/io/scenario.h"
#include "tests/fuzz/fuzz_common.h"

namespace esim::fuzz {

inline void checkAcceptedScenario(const Scenario& s) {
  const std::string yaml = scenarioToYaml(s);
  Scenario again;
  if (!accepts([&] { again = parseScenario(yaml, s.sourceName, {}); }))
    finding("scenarioToYaml of an accepted scenario is refused:\n" + yaml);
  if (!(again == s)) finding("parse(toYaml(s)) != s for:\n" + yaml);
  if (scenarioHash(again) != scenarioHash(s)) finding("scenarioHash differs after a round trip");
  if (frameCount(s) < 1) finding("frameCount < 1");
  (void)makeSlabSpec(s);
  (void)makeMeshingOptions(s);
  accepts([&] { (void)makeToolPath(s); });
  (void)scenarioSummary(s);
}

}  // namespace esim::fuzz
