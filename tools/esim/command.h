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
#include <cctype>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "sim/core_error.h"
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

// An option the command would silently ignore is bad input: throws an Input error naming
// the first of `options` that was given, "<command>: --x <why>" (e.g. why = "is an option of
// the blade-sweep table, which --only-update skips").
inline void refuseGiven(const std::vector<const CLI::Option*>& options, const std::string& command,
                        const std::string& why) {
  for (const CLI::Option* o : options)
    ESIM_VERIFY(o->count() == 0, command + ": " + o->get_name() + " " + why);
}

// A file the command will write, checked before any work: not a folder, ending in `ext`
// (".png"; any case), in a folder that exists. Throws Input errors "<option> 'PATH' is a
// folder; expected a .png file name", "... must end in .png", "<option> 'PATH': the folder
// 'DIR' does not exist" (option e.g. "esim plot: -o").
inline void checkOutputFileName(const std::string& option, const std::string& path,
                                const std::string& ext) {
  namespace fs = std::filesystem;
  const fs::path file = path;
  std::error_code ec;
  std::string got = file.extension().string();
  for (char& c : got) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  ESIM_VERIFY(!fs::is_directory(file, ec),
              option + " '" + path + "' is a folder; expected a " + ext + " file name");
  ESIM_VERIFY(got == ext, option + " '" + path + "' must end in " + ext);
  const fs::path parent = file.has_parent_path() ? file.parent_path() : fs::path(".");
  ESIM_VERIFY(fs::is_directory(parent, ec),
              option + " '" + path + "': the folder '" + parent.string() + "' does not exist");
}

// exit codes (tools/app/exit_codes.h, documented in README)
using ::esim::exitCodeOf;
using ::esim::kExitBadInput;
using ::esim::kExitFailure;
using ::esim::kExitInternal;
using ::esim::kExitMismatch;
using ::esim::kExitOk;

}  // namespace esim::cli
