// cmd_run.cpp - `esim run SCENARIO`: the command line of a run (tools/app/run.h does it).
#include <memory>

#include "tools/app/run.h"
#include "tools/esim/command.h"

namespace esim::cli {
namespace {

Registrar reg({"run"}, "Run a scenario: simulate, render, encode, report",
              [](CLI::App& app) -> Runner {
                auto opt = std::make_shared<app::RunOptions>();
                app.add_option("scenario", opt->scenario, "scenario YAML file")->required();
                app.add_option("-o,--out", opt->outDir,
                               "output folder (default out/<name>); never a folder of other "
                               "files, an earlier run only with --overwrite");
                app.add_option("--frames", opt->frames,
                               "number of frames (default: duration x fps)")
                    ->check(CLI::Range(1, 100000000));
                app.add_option("--fields", opt->fieldsEvery,
                               "write every Nth frame's fields as VTU (0: none)")
                    ->check(CLI::Range(0, 100000000));
                app.add_option("--set", opt->sets, "override a scenario field: key.path=value");
                app.add_flag("--no-video", opt->noVideo, "skip video encoding");
                app.add_flag("--overwrite", opt->overwrite,
                             "replace an earlier ESim run in the output folder");
                app.add_flag("-q,--quiet", opt->quiet, "no progress output");
                app.add_flag("--plots", opt->plots,
                             "also write timing.png (stage times per frame, power, temperature, "
                             "removed tets; needs python3-matplotlib, else a warning)");
                return [opt] { return app::runScenario(*opt); };
              });

}  // namespace
}  // namespace esim::cli
