// Hard cases (issue #12): extreme but allowed values of every material parameter. Each case
// sets one material.* field of a full-physics scenario (electric, thermal, boiling,
// structural, rupture, sigma(T), Arrhenius damage; a blade cutting a 30 x 30 x 10 mm slab) to
// the smallest or largest value the schema allows (`esim validate --reference`; an open bound
// at 0 is replaced by 1e-6 times the default, the open upper bound of the Arrhenius factor by
// 1e300, the open upper bound 0.5 of Poisson's ratio by 0.5 - 1e-6), through the scenario path
// a run takes (parseScenario with a --set override, app::checkRunnable, app::makeSimulationConfig,
// app::buildMesh). The table says what must happen: the 10 frames run with every invariant of
// hard::FrameChecker (and a finite damage integral), or the case is refused up front (Input,
// naming the field), or the run stops with a Run error saying why.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <ostream>
#include <set>
#include <string>
#include <vector>

#include "hard_case.h"
#include "sim/io/scenario.h"
#include "tools/app/run_config.h"

namespace esim {
namespace {

using hard::FrameChecker;
using hard::Invariants;
using hard::MaxPrinciple;

enum class Outcome { Runs, RefusedUpFront, RunError };

struct Extreme {
  std::string field;  // material.* key
  double value;
  Outcome outcome = Outcome::Runs;
  std::string message;  // a part of the error's message (refused, run error)
};

// the case in test names and failure messages
void PrintTo(const Extreme& e, std::ostream* os) { *os << e.field << " = " << e.value; }

std::string yamlNumber(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

// a 30 x 30 x 10 mm slab (2.5 mm grid) on a 20 mm pad; a 400 V blade pressed 0.2 mm into the
// top face cuts 6 mm in 10 frames; every effect on; backward Euler (the explicit default's
// sub-step bound is validate_test.cpp's case)
constexpr const char* kScene = R"(name: hard_material
mesh:
  source: slab
  slab: {size_m: [0.03, 0.03, 0.01], nodes_per_axis: [13, 13, 5]}
return_electrode: {center_m: [0, 0, 0], radius_m: 0.02}
tool:
  shape: blade
  voltage_v: 400
  path:
    - {t_s: 0.0, position_m: [-0.003, 0, 0.0098]}
    - {t_s: 0.3333333333333333, position_m: [0.003, 0, 0.0098]}
physics: [electric, thermal, boiling, structural, rupture]
effects: {temperature_dependent_conductivity: true, thermal_damage: true}
solvers:
  thermal: {integrator: backward-euler}
time: {fps: 30, duration_s: 0.3333333333333333}
output: {video: false, hashes: false}
)";

// the schema's range of a field: "(0, 1e+08]" -> lo, hi, open ends
struct Range {
  double lo, hi;
  bool openLo, openHi;
  bool contains(double v) const {
    return (openLo ? v > lo : v >= lo) && (openHi ? v < hi : v <= hi);
  }
};

Range schemaRange(const std::string& field) {
  for (const ScenarioFieldInfo& f : scenarioFields()) {
    if (f.path != field) continue;
    const std::string& a = f.allowed;
    const size_t comma = a.find(',');
    auto number = [](std::string s) {
      s.erase(0, s.find_first_not_of(' '));
      return s == ".inf" ? INFINITY : std::stod(s);
    };
    return {number(a.substr(1, comma - 1)), number(a.substr(comma + 1, a.size() - comma - 2)),
            a.front() == '(', a.back() == ')'};
  }
  ADD_FAILURE() << "no schema field " << field;
  return {0, 0, false, false};
}

// the outcomes other than Runs: E = 1e12 Pa and a critical stress of 0.0245 Pa break every tet
// that warms by a trace (the implicit heat step warms them all) in the first frame; a boiling
// temperature of 0 C or an initial temperature of 300 C put boiling below the initial state
const std::vector<Extreme>& extremes() {
  static const std::vector<Extreme> table = {
      {"material.heat_capacity_j_per_m3k", 3.82, Outcome::Runs, ""},
      {"material.heat_capacity_j_per_m3k", 1e8, Outcome::Runs, ""},
      {"material.thermal_conductivity_w_per_mk", 0.502e-6, Outcome::Runs, ""},
      {"material.thermal_conductivity_w_per_mk", 100, Outcome::Runs, ""},
      {"material.electric_conductivity_s_per_m", 0.144e-6, Outcome::Runs, ""},
      {"material.electric_conductivity_s_per_m", 1000, Outcome::Runs, ""},
      {"material.youngs_modulus_pa", 4.75e-2, Outcome::Runs, ""},
      {"material.youngs_modulus_pa", 1e12, Outcome::RunError, "every element"},
      {"material.poisson_ratio", 0, Outcome::Runs, ""},
      {"material.poisson_ratio", 0.5 - 1e-6, Outcome::Runs, ""},
      {"material.critical_stress_pa", 2.45e-2, Outcome::RunError, "every element"},
      {"material.critical_stress_pa", 1e12, Outcome::Runs, ""},
      // the nonlocal criterion's radius: 0 (the paper's), and 5 cm, wider than the slab
      {"material.critical_stress_radius_m", 0, Outcome::Runs, ""},
      {"material.critical_stress_radius_m", 0.05, Outcome::Runs, ""},
      // debris: none, and every piece cut loose (1 litre, larger than the slab)
      {"material.debris_volume_m3", 0, Outcome::Runs, ""},
      {"material.debris_volume_m3", 1e-3, Outcome::Runs, ""},
      {"material.vapor_liquid_volume_ratio", 1, Outcome::Runs, ""},
      {"material.vapor_liquid_volume_ratio", 1e4, Outcome::Runs, ""},
      {"material.max_vapor_expansion", 0, Outcome::Runs, ""},
      {"material.max_vapor_expansion", 1e4, Outcome::Runs, ""},
      {"material.density_kg_per_m3", 1.06e-3, Outcome::Runs, ""},
      {"material.density_kg_per_m3", 1e5, Outcome::Runs, ""},
      {"material.water_fraction", 0, Outcome::Runs, ""},
      {"material.water_fraction", 1, Outcome::Runs, ""},
      {"material.latent_heat_j_per_kg", 2.256, Outcome::Runs, ""},
      {"material.latent_heat_j_per_kg", 1e8, Outcome::Runs, ""},
      {"material.boiling_temperature_c", 0, Outcome::RefusedUpFront,
       "material.boiling_temperature_c"},
      {"material.boiling_temperature_c", 300, Outcome::Runs, ""},
      {"material.initial_temperature_c", -50, Outcome::Runs, ""},
      {"material.initial_temperature_c", 300, Outcome::RefusedUpFront,
       "material.initial_temperature_c"},
      {"material.conductivity_temp_coeff_per_k", -1, Outcome::Runs, ""},
      {"material.conductivity_temp_coeff_per_k", 1, Outcome::Runs, ""},
      {"material.desiccated_conductivity_factor", 1e-8, Outcome::Runs, ""},
      {"material.desiccated_conductivity_factor", 1, Outcome::Runs, ""},
      {"material.arrhenius_a_per_s", 7.39e33, Outcome::Runs, ""},
      {"material.arrhenius_a_per_s", 1e300, Outcome::Runs, ""},
      {"material.arrhenius_ea_j_per_mol", 0.2577, Outcome::Runs, ""},
      {"material.arrhenius_ea_j_per_mol", 1e7, Outcome::Runs, ""},
  };
  return table;
}

// the table lists each field's minimum, then its maximum
std::string caseName(const ::testing::TestParamInfo<Extreme>& info) {
  return info.param.field.substr(std::string("material.").size()) +
         (info.index % 2 ? "_max" : "_min");
}

// every material.* field of the schema is in the table, at both ends
TEST(HardMaterialTable, CoversEveryMaterialFieldAtBothEnds) {
  std::set<std::string> schema, table;
  for (const ScenarioFieldInfo& f : scenarioFields())
    if (f.path.rfind("material.", 0) == 0) schema.insert(f.path);
  for (const Extreme& e : extremes()) table.insert(e.field);
  EXPECT_EQ(schema, table);
  for (const std::string& f : schema) {
    int n = 0;
    for (const Extreme& e : extremes()) n += e.field == f;
    EXPECT_EQ(n, 2) << f;
  }
}

class HardMaterial : public ::testing::TestWithParam<Extreme> {};

TEST_P(HardMaterial, RunsOrSaysWhyNot) {
  const Extreme& x = GetParam();
  const Range range = schemaRange(x.field);
  ASSERT_TRUE(range.contains(x.value)) << x.value << " is outside the schema's range";
  // the schema accepts it (the value is allowed) ...
  Scenario s;
  ASSERT_NO_THROW(
      s = parseScenario(kScene, "hard_material.yaml", {x.field + "=" + yamlNumber(x.value)}));
  // ... then what `esim validate` checks, then the run's set-up
  std::unique_ptr<Simulation> sim;
  try {
    app::checkRunnable(s);
    sim = std::make_unique<Simulation>(app::buildMesh(s), app::makeSimulationConfig(s));
  } catch (const Error& e) {
    std::printf("refused up front (%s): %s\n", errorKindName(e.kind()), e.what());
    EXPECT_EQ(x.outcome, Outcome::RefusedUpFront) << e.what();
    EXPECT_EQ(e.kind(), ErrorKind::Input) << e.what();
    EXPECT_TRUE(hard::contains(e.what(), x.message)) << e.what();
    return;
  }
  Invariants inv;
  inv.maxPrinciple = MaxPrinciple::Lower;  // a positive Joule source, insulated
  inv.potentialBounds = true;
  FrameChecker check(*sim, inv);
  const int frames = frameCount(s);
  ASSERT_EQ(frames, 10);
  try {
    for (int f = 0; f < frames && check.ok(); ++f) {
      check.step();
      const ThermalState& t = *sim->thermalState();
      for (size_t e = 0; e < t.damageOmega.size(); ++e) {
        ASSERT_FALSE(std::isnan(t.damageOmega[e])) << "frame " << f << " tet " << e;
        ASSERT_TRUE(std::isfinite(t.coagulationTet[e])) << "frame " << f << " tet " << e;
      }
    }
  } catch (const Error& e) {
    std::printf("stopped at frame %d (%s): %s\n", check.frames(), errorKindName(e.kind()),
                e.what());
    EXPECT_EQ(x.outcome, Outcome::RunError) << e.what();
    EXPECT_EQ(e.kind(), ErrorKind::Run) << e.what();
    EXPECT_TRUE(hard::contains(e.what(), x.message)) << e.what();
    return;
  }
  EXPECT_EQ(x.outcome, Outcome::Runs);
  std::printf("%d frames, %.4g J delivered, temperatures %.6g .. %.6g C, %d tets removed\n",
              check.frames(), sim->energyDeliveredJ(), check.minSeenC(), check.maxSeenC(),
              sim->removedTets());
}

INSTANTIATE_TEST_SUITE_P(Extremes, HardMaterial, ::testing::ValuesIn(extremes()), caseName);

}  // namespace
}  // namespace esim
