// cmd_validate.cpp - `esim validate SCENARIO... [--set k=v ...] [--reference]`.
//
// 1. Load each scenario with the overrides (sim/io/scenario.h): keys, types, ranges,
//    phase dependencies, tool path and asset files are all checked; then every check the
//    set-up of `esim run` makes before its first frame (tools/app/run_config.h:
//    checkRunnable), so that a file that validates never fails at set-up.
// 2. Print "ok <file>: <summary>" or the error with file:line:col, and go on; a warning the
//    run would give from the configuration alone (sim/simulation.h: configWarnings) goes to
//    stderr as "warning: <file>: ..." and leaves the file valid.
// 3. Exit 2 when any file is invalid. `--reference` prints the Markdown schema reference.
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "sim/core_error.h"
#include "sim/io/scenario.h"
#include "sim/message_text.h"
#include "sim/simulation.h"
#include "tools/app/run_config.h"
#include "tools/esim/command.h"

namespace {

struct ValidateOptions {
  std::vector<std::string> files;
  std::vector<std::string> overrides;
  bool reference = false;
};

int runValidate(const ValidateOptions& opt) {
  if (opt.reference) {
    std::cout << esim::scenarioReferenceMarkdown();
    if (opt.files.empty()) return esim::cli::kExitOk;
  }
  if (opt.files.empty())
    throw esim::Error("validate: give at least one scenario file (or --reference)");
  int invalid = 0;
  for (const auto& file : opt.files) {
    try {
      const esim::Scenario s = esim::loadScenario(file, opt.overrides);
      esim::app::checkRunnable(s);
      std::cout << "ok " << s.sourceName << ": " << esim::scenarioSummary(s) << "\n";
      for (const std::string& w : esim::configWarnings(esim::app::makeSimulationConfig(s)))
        std::cerr << esim::printableMessage("warning: " + s.sourceName + ": " + w) << "\n";
    } catch (const esim::Error& e) {
      std::cerr << "error: " << esim::printableMessage(e.what()) << "\n";
      ++invalid;
    }
  }
  if (invalid > 0) {
    std::cerr << invalid << " of " << opt.files.size() << " scenario"
              << (opt.files.size() == 1 ? "" : "s") << " invalid\n";
    return esim::cli::kExitBadInput;
  }
  return esim::cli::kExitOk;
}

const esim::cli::Registrar registerValidate(
    {"validate"}, "Check scenario files (keys, types, ranges, phases, tool path, assets)",
    [](CLI::App& app) -> esim::cli::Runner {
      auto opt = std::make_shared<ValidateOptions>();
      app.footer(
          "Examples:\n"
          "  esim validate scenarios/*.yaml\n"
          "  esim validate scenarios/paper_slab.yaml --set tool.voltage_v=60 --set "
          "physics=[electric]\n"
          "  esim validate --reference > docs/scenario-reference.md\n"
          "Prints 'ok FILE: summary' or 'error: FILE:LINE:COL: field: message' per file,\n"
          "and 'warning: FILE: ...' on stderr for what the run would warn of from the\n"
          "configuration alone (the file stays valid).\n"
          "Exit codes: 0 all valid, 2 some file invalid (or bad options).");
      app.add_option("scenarios", opt->files, "scenario YAML files (- reads standard input)");
      app.add_option("--set", opt->overrides,
                     "override a field: key.path=value (YAML value), repeatable")
          ->allow_extra_args(false);
      app.add_flag("--reference", opt->reference,
                   "print the scenario reference (Markdown) generated from the schema");
      return [opt] { return runValidate(*opt); };
    });

}  // namespace
