// main.cpp - the `esim` command: parses the command line and runs one sub-command.
//
// 1. Build the command tree from the registry (tools/esim/command.h).
// 2. Parse; CLI11 prints --help and usage errors.
// 3. Run the chosen command; an esim::Error becomes a message and the exit code of its kind
//    (input 2, run 1, internal 4: command.h).
// Before all that, OpenBLAS's kernels (useFastBlasKernels), the memory bound
// (boundAddressSpace) and transparent huge pages off (disableTransparentHugePages; both
// tools/app/memory_room.h).
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <map>
#include <sstream>
#include <string>

#include "sim/core_error.h"
#include "sim/message_text.h"
#include "tools/app/build_info.h"
#include "tools/app/memory_room.h"
#include "tools/esim/command.h"

namespace esim::cli {
std::vector<CommandSpec>& commandRegistry() {
  static std::vector<CommandSpec> registry;
  return registry;
}
}  // namespace esim::cli

extern "C" char* openblas_get_corename(void);

namespace {

// prints an ESim error and returns its exit code (see command.h)
int reportError(const esim::Error& e) {
  std::cerr << (e.kind() == esim::ErrorKind::Internal ? "esim: internal error: " : "esim: error: ")
            << esim::printableMessage(e.what()) << "\n";
  return esim::cli::exitCodeOf(e.kind());
}

// OpenBLAS 0.3.21 (Debian 12) picks its kernels from the CPU model; a model it does not
// know (this machine reports "Intel(R) Xeon(R) Processor", an AVX-512 part) gets the
// generic SSE3 "Prescott" kernels. It reads OPENBLAS_CORETYPE only while loading, so when
// it chose Prescott on a CPU with AVX-512 (or AVX2 + FMA) we set SkylakeX (Haswell) and
// run ourselves again. Measured on scenarios/slab_cut.yaml (50 frames): rebuild 939 ->
// 735 ms, solve_potential 21.0 -> 15.8 ms per frame. An explicit OPENBLAS_CORETYPE, or
// ESIM_KEEP_BLAS_CORE=1, is left alone; if exec fails we go on with Prescott.
void useFastBlasKernels(char** argv) {
  if (std::getenv("OPENBLAS_CORETYPE") || std::getenv("ESIM_KEEP_BLAS_CORE")) return;
  const char* core = openblas_get_corename();
  if (!core || strcasecmp(core, "prescott") != 0) return;
  __builtin_cpu_init();
  const char* want = nullptr;
  if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512dq") &&
      __builtin_cpu_supports("avx512vl") && __builtin_cpu_supports("avx512bw"))
    want = "SkylakeX";
  else if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma"))
    want = "Haswell";
  if (!want) return;
  setenv("OPENBLAS_CORETYPE", want, 1);
  execv("/proc/self/exe", argv);
}

}  // namespace

int main(int argc, char** argv) {
  useFastBlasKernels(argv);
  esim::app::boundAddressSpace();
  esim::app::disableTransparentHugePages();  // before any thread (they inherit it)
  esim::app::keepLargeBlocksInTheHeap();
  esim::app::watchOutOfMemory();  // after the exec of useFastBlasKernels, before any thread
  using namespace esim::cli;
  CLI::App app{
      "esim - physics-based electrosurgery simulation rendered to video, headless.\n"
      "Examples:\n"
      "  esim run scenarios/paper_slab.yaml -o out/demo\n"
      "  esim run scenarios/paper_slab.yaml --frames 30 --set tool.voltage_v=60\n"
      "  esim validate scenarios/*.yaml\n"
      "  esim sweep scenarios/sweeps/slab_cut_8.yaml -o out/slab_cut_8 --workers 2\n"
      "  esim mesh-info assets/liver.obj\n"
      "  esim bench electric --sizes 1013,50000 --csv electric.csv\n"
      "Exit codes: 0 ok, 1 run failed (outputs so far kept, marked partial), 2 bad input "
      "(scenario, mesh, option), 3 comparison mismatch, 4 internal error (a bug)."};
  app.require_subcommand(1);
  app.set_help_all_flag("--help-all", "Show help for all sub-commands");
  // the version and the git commit of the tree it was built from (timing.json and
  // hashes.json record the same)
  app.set_version_flag("--version", esim::app::buildInfoLine(esim::app::buildInfo()),
                       "Print esim's version, the git commit it was built from, and exit");

  // 1. command tree
  std::map<CLI::App*, Runner> runners;
  std::map<std::string, CLI::App*> groups;
  for (auto& spec : commandRegistry()) {
    CLI::App* parent = &app;
    std::string key;
    for (size_t i = 0; i + 1 < spec.path.size(); ++i) {
      key += spec.path[i] + "/";
      auto it = groups.find(key);
      if (it == groups.end()) {
        CLI::App* g = parent->add_subcommand(
            spec.path[i], spec.path[i] == "dataset"
                              ? "Sweep folders (esim sweep -o DIR): verify, run one variant"
                              : "Benchmarks (tables, never pass/fail)");
        g->require_subcommand(1);
        it = groups.emplace(key, g).first;
      }
      parent = it->second;
    }
    CLI::App* sub = parent->add_subcommand(spec.path.back(), spec.description);
    runners[sub] = spec.setup(*sub);
  }

  // 2. parse (an unknown command word first: CLI11 says "A subcommand is required")
  {
    CLI::App* level = &app;
    std::string path = "esim";
    for (int i = 1; i < argc; ++i) {
      const std::string word = argv[i];
      if (word.empty() || word[0] == '-') break;  // an option: CLI11's to judge
      const auto subs = level->get_subcommands([](CLI::App*) { return true; });
      if (subs.empty()) break;  // a command's own arguments
      CLI::App* next = nullptr;
      std::string names;
      for (CLI::App* sub : subs) {
        if (sub->get_name() == word) next = sub;
        names += (names.empty() ? "" : ", ") + sub->get_name();
      }
      if (next == nullptr) {
        std::cerr << "esim: error: " << path << ": unknown command " << esim::quoteInMessage(word)
                  << "; expected one of: " << names << " (" << path << " --help)\n";
        return kExitBadInput;
      }
      path += " " + word;
      level = next;
    }
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // CLI11's message quotes the value it refused as given: each line escaped and cut at 300
    // characters, a 5000-character --frames or a terminal's escape no longer echoed
    std::ostringstream err;
    const int code = app.exit(e, std::cout, err);
    std::cerr << esim::printableMessage(err.str(), 300);
    return code == 0 ? kExitOk : kExitBadInput;
  } catch (const esim::Error& e) {
    return reportError(e);
  }

  // 3. run the deepest chosen sub-command; an option or argument given an empty value (an
  // unset shell variable: -o "$OUT") is refused, where -o "" ran into the default folder and
  // --csv "" or --report "" wrote nothing, all without a word
  CLI::App* chosen = &app;
  for (;;) {
    for (const CLI::Option* o : chosen->get_options()) {
      const std::string name = o->get_name();
      if (name == "--run-args") continue;  // (no more run options: allowed)
      // an option whose value is optional (esim run --labels [preview]) given without one has
      // an empty result: it was refused too, so `--labels -o DIR` (the README's) exited 2
      if (o->get_expected_min() == 0) continue;
      for (const std::string& value : o->results())
        if (value.empty())
          return reportError(esim::Error(
              name + (o->get_description().empty() ? "" : " (" + o->get_description() + ")") +
              ": an empty value (an unset shell variable?)"));
    }
    if (chosen->get_subcommands().empty()) break;
    chosen = chosen->get_subcommands().front();
  }
  auto it = runners.find(chosen);
  if (it == runners.end()) {
    std::cerr << app.help();
    return kExitBadInput;
  }
  try {
    return it->second();
  } catch (const esim::Error& e) {
    return reportError(e);
  } catch (const std::bad_alloc&) {
    // (a run's frames report theirs in its summary; this is the set-up's, or another command's)
    std::cerr << "esim: error: out of memory (a smaller mesh, fewer phases, or another electric "
                 "strategy: solvers.electric.strategy)";
    if (!esim::app::addressSpaceBound().empty())
      std::cerr << "; " << esim::app::addressSpaceBound();
    std::cerr << "\n";
    return kExitFailure;
  } catch (const std::filesystem::filesystem_error& e) {
    std::cerr << "esim: error: " << esim::printableMessage(e.what()) << "\n";
    return kExitFailure;
  } catch (const std::exception& e) {
    std::cerr << "esim: internal error: " << esim::printableMessage(e.what()) << "\n";
    return kExitInternal;
  }
}
