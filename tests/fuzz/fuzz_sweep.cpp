// fuzz_sweep.cpp - libFuzzer target: a sweep file (`esim sweep SPEC`) on any text, read by
// loadSweepSpec from a file beside a small base scenario (base.yaml: a graded slab, a tool
// path, so that the path transforms and the planned cut's move are reached), then, for a
// sweep of at most kMaxVariants variants, expandSweep without the mesh (the checks `esim
// sweep --dry-run` makes but the slab's meshing), and the checks of scenario_oracle.h on
// every variant's scenario. Opt-in: tools/fuzz SECONDS fuzz_sweep (not in its default list).
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "tests/fuzz/fuzz_common.h"
#include "tests/fuzz/scenario_oracle.h"
#include "tools/app/sweep_spec.h"

using namespace esim;

namespace {

constexpr std::size_t kMaxVariants = 16;  // larger sweeps are read, not expanded

const char* const kBase = R"(name: base
mesh:
  source: slab
  slab:
    size_m: [0.06, 0.03, 0.01]
    nodes: 300
    grading: {enabled: true, from_m: [-0.02, 0, 0.01], to_m: [0.02, 0, 0.01], width_m: 0.004}
tool:
  shape: blade
  voltage_v: 100
  path:
    - {t_s: 0.0, position_m: [-0.02, 0, 0.0098], orientation_deg: [0, 0, 0]}
    - {t_s: 1.0, position_m: [0.02, 0, 0.0098], orientation_deg: [0, 0, 10]}
physics: [electric, thermal]
time: {fps: 10, duration_s: 1.0}
)";

// the folder of this process's sweep file and base scenario, written once
const std::filesystem::path& folder() {
  static const std::filesystem::path dir = [] {
    const std::filesystem::path d =
        std::filesystem::temp_directory_path() / ("esim_fuzz_sweep_" + std::to_string(::getpid()));
    std::filesystem::create_directories(d);
    std::ofstream(d / "base.yaml") << kBase;
    return d;
  }();
  return dir;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::filesystem::path file = folder() / "sweep.yaml";
  {
    std::ofstream os(file, std::ios::binary | std::ios::trunc);
    os.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
    if (!os) fuzz::finding("cannot write " + file.string());
  }
  app::SweepSpec spec;
  if (!fuzz::accepts([&] { spec = app::loadSweepSpec(file.string()); })) return 0;
  const std::size_t n = app::sweepVariantCount(spec);
  if (n < 1) fuzz::finding("an accepted sweep has no variant");
  if (n > kMaxVariants) return 0;
  std::vector<app::SweepVariant> variants;
  if (!fuzz::accepts([&] { variants = app::expandSweep(spec, false); })) return 0;
  if (variants.size() != n) fuzz::finding("expandSweep gave another count than sweepVariantCount");
  for (std::size_t i = 0; i < n; ++i) {
    if (variants[i].index != static_cast<int>(i)) fuzz::finding("variants out of order");
    if (variants[i].id != app::variantId(i, n)) fuzz::finding("a variant's id is not variantId");
    fuzz::checkAcceptedScenario(variants[i].scenario);
  }
  // the same file, the same variants (the draws are portable and seeded)
  if (n <= 4) {
    std::vector<app::SweepVariant> again;
    if (!fuzz::accepts([&] { again = app::expandSweep(spec, false); }))
      fuzz::finding("the same sweep refused the second time");
    for (std::size_t i = 0; i < n; ++i)
      if (again[i].overrides != variants[i].overrides || again[i].values != variants[i].values)
        fuzz::finding("the same sweep gave other variants the second time");
  }
  return 0;
}
