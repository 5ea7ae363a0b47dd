// cmd_sweep.cpp - `esim sweep SPEC -o DIR`: the command line of a sweep (tools/app/sweep.h
// does it).
#include <memory>
#include <sstream>

#include "sim/core_error.h"
#include "tools/app/sweep.h"
#include "tools/esim/command.h"

namespace esim::cli {
namespace {

// parses extra `esim run` options with `esim run`'s own definition (so an option added to
// run, e.g. --labels, is accepted here without a change)
void checkRunOptions(const std::vector<std::string>& options) {
  for (const auto& spec : commandRegistry()) {
    if (spec.path != std::vector<std::string>{"run"}) continue;
    CLI::App app{"esim run"};
    // the runner holds the options the parse writes into: it lives until the parse is done
    const Runner keep = spec.setup(app);
    std::vector<std::string> args{"esim", "scenario.yaml"};
    args.insert(args.end(), options.begin(), options.end());
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    try {
      app.parse(static_cast<int>(argv.size()), argv.data());
    } catch (const CLI::ParseError& e) {
      throw Error(std::string("esim run does not take them: ") + e.what());
    }
    return;
  }
}

std::vector<std::string> splitWords(const std::string& text) {
  std::istringstream in(text);
  std::vector<std::string> words;
  for (std::string w; in >> w;) words.push_back(w);
  return words;
}

Registrar reg(
    {"sweep"}, "Run every variant of a sweep file (grid and random draws over a scenario)",
    [](CLI::App& app) -> Runner {
      auto opt = std::make_shared<app::SweepOptions>();
      auto runArgs = std::make_shared<std::string>();
      app.add_option("spec", opt->spec, "sweep file (scenarios/sweeps/README.md)")->required();
      app.add_option("-o,--out", opt->outDir,
                     "the sweep's folder: new, empty, or an earlier run of this sweep to resume");
      // what only a local sweep, or only a Slurm one, reads (the other would ignore it)
      std::vector<const CLI::Option*> localOnly, slurmOnly;
      localOnly.push_back(
          app.add_option("--workers", opt->workers, "variants run at once on this machine")
              ->check(CLI::Range(1, 1024)));
      app.add_flag("--retry-failed", opt->retryFailed,
                   "run the variants that failed earlier again (interrupted ones always are)");
      app.add_option("--run-args", *runArgs,
                     "more esim run options for every variant, e.g. --run-args=\"--labels\"");
      app.add_flag("--dry-run", opt->dryRun,
                   "expand and check every variant, list them, write nothing");
      app.add_flag("-q,--quiet", opt->quiet, "no progress output");
      app.add_flag("--slurm", opt->slurm,
                   "write DIR/slurm/sweep.sbatch, a job array of one variant per task, instead "
                   "of running here");
      app.add_flag("--submit", opt->submit, "with --slurm: sbatch the script and wait for it");
      slurmOnly.push_back(
          app.add_option("--mem-mb", opt->memMb, "Slurm: memory per task in MB (default: measured)")
              ->check(CLI::Range(1, 100000000)));
      slurmOnly.push_back(
          app.add_option("--time-min", opt->timeMin,
                         "Slurm: time limit per task in minutes (default: measured)")
              ->check(CLI::Range(1, 100000000)));
      slurmOnly.push_back(
          app.add_option("--cpus", opt->cpus,
                         "Slurm: CPUs per task (default: the scene's solver threads, +1 for a "
                         "background rebuild)")
              ->check(CLI::Range(1, 4096)));
      slurmOnly.push_back(app.add_option("--max-parallel", opt->maxParallel,
                                         "Slurm: at most this many tasks at once (the array's %N)")
                              ->check(CLI::Range(1, 1000000)));
      slurmOnly.push_back(
          app.add_option("--sbatch-arg", opt->sbatchArgs,
                         "Slurm: one more #SBATCH line, e.g. --sbatch-arg=--partition=long"));
      return [opt, runArgs, localOnly, slurmOnly] {
        if (opt->slurm)
          refuseGiven(localOnly, "sweep",
                      "runs variants on this machine; with --slurm, Slurm runs them "
                      "(--max-parallel limits how many at once)");
        else
          refuseGiven(slurmOnly, "sweep", "is a Slurm option; it goes with --slurm");
        opt->runArgs = splitWords(*runArgs);
        return app::runSweep(*opt, checkRunOptions);
      };
    });

}  // namespace
}  // namespace esim::cli
