// cmd_dataset.cpp - `esim dataset verify DIR` (every output re-hashed against the manifest)
// and `esim dataset run DIR VARIANT` (one variant of a sweep folder: what a Slurm task runs).
#include <iostream>
#include <memory>

#include "sim/message_text.h"
#include "tools/app/dataset.h"
#include "tools/app/sweep.h"
#include "tools/esim/command.h"

namespace esim::cli {
namespace {

struct VerifyOptions {
  std::string dir;
  bool quiet = false;
};

int verify(const VerifyOptions& opt) {
  const app::VerifyReport r = app::verifyDataset(opt.dir);
  const std::string dir = printablePath(opt.dir);
  for (const auto& p : r.problems) std::cout << dir << "/" << printableMessage(p, 600) << "\n";
  if (!opt.quiet || !r.problems.empty()) {
    std::cout << "verify " << dir << ": " << r.variants << " variants, " << r.complete
              << " complete (" << r.filesChecked << " files re-hashed)";
    if (r.notComplete) std::cout << ", " << r.notComplete << " not complete (not checked)";
    std::cout << ": "
              << (r.problems.empty() ? "all match the manifest"
                                     : std::to_string(r.problems.size()) +
                                           (r.problems.size() == 1 ? " problem" : " problems"))
              << "\n";
  }
  // a dataset two builds of esim made (a sweep resumed after the code changed): said, not a
  // problem (its files still match the manifest)
  if (r.builds.size() > 1) std::cout << "  note: " << app::datasetBuildsText(r.builds);
  return r.problems.empty() ? kExitOk : kExitMismatch;
}

Registrar verifyReg(
    {"dataset", "verify"},
    "Re-hash every output of a sweep folder against its manifest (exit 3 on a "
    "difference)",
    [](CLI::App& app) -> Runner {
      auto opt = std::make_shared<VerifyOptions>();
      app.add_option("dir", opt->dir, "the sweep's folder (esim sweep -o DIR)")->required();
      app.add_flag("-q,--quiet", opt->quiet, "print only the problems");
      return [opt] { return verify(*opt); };
    });

struct RunOneOptions {
  std::string dir, variant;
  bool retryFailed = false;
};

Registrar runReg(
    {"dataset", "run"}, "Run one variant of a sweep folder (what each Slurm array task runs)",
    [](CLI::App& app) -> Runner {
      auto opt = std::make_shared<RunOneOptions>();
      app.add_option("dir", opt->dir, "the sweep's folder")->required();
      app.add_option("variant", opt->variant, "its id (v0003) or index (3)")->required();
      app.add_flag("--retry-failed", opt->retryFailed, "run it even if it failed earlier");
      return [opt] { return app::runSweepVariant(opt->dir, opt->variant, opt->retryFailed); };
    });

}  // namespace
}  // namespace esim::cli
