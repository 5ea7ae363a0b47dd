// command.h - registry of `esim` sub-commands.
//
// Each command lives in its own file under tools/esim/ and registers itself with
// a static Registrar object, so main.cpp never changes when a command is added:
//
//   static esim::cli::Registrar reg({"bench", "electric"}, "Electric solver benchmark",
//     [](CLI::App& app) -> esim::cli::Runner {
//       auto opt = std::make_shared<Options>();
//       app.add_option("--frames", opt->frames, "frames per run");
//       return [opt] { return benchElectric(*opt); };   // returns the exit code
//     });
//
// A runner returns the process exit code; it reports errors by throwing esim::Error, which
// main prints as "esim: error: <message>" and turns into the exit code of its kind.
#pragma once

#include <CLI/CLI.hpp>
#include <functional>
#include <string>
#include <vector>

#include "tools/app/exit_codes.h"

namespace esim::cli {

using Runner = std::function<int()>;
using Setup = std::function<Runner(CLI::App&)>;

struct CommandSpec {
  std::vector<std::string> path;  // e.g. {"bench", "electric"}
  std::string description;
  Setup setup;
};

// all registered commands, in registration order
std::vector<CommandSpec>& commandRegistry();

struct Registrar {
  Registrar(std::vector<std::string> path, std::string description, Setup setup) {
    commandRegistry().push_back({std::move(path), std::move(description), std::move(setup)});
  }
};

// exit codes (tools/app/exit_codes.h, documented in README)
using ::esim::exitCodeOf;
using ::esim::kExitBadInput;
using ::esim::kExitFailure;
using ::esim::kExitInternal;
using ::esim::kExitMismatch;
using ::esim::kExitOk;

}  // namespace esim::cli
