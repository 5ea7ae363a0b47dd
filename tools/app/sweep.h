// sweep.h - `esim sweep SPEC -o DIR`: every variant of a sweep file run, here or on a
// Slurm cluster, into one folder with a manifest (the folder: dataset.h).
//
// 1. Read the sweep file, expand and check every variant (sweep_spec.h) and the run
//    options; any problem is bad input (exit 2) before anything is written.
// 2. DIR: created, or an earlier sweep's folder resumed (the same variants and run options,
//    else exit 2); sweep.yaml, sweep.json and each runs/<id>/scenario.yaml written.
// 3. Local (default): the variants not complete run as child processes, `esim run
//    runs/<id>/scenario.yaml -o runs/<id>/run -q <run options>`, --workers at a time, each
//    in its own process group; a progress line for the whole sweep. A complete variant is
//    skipped; a failed one is recorded with its message and the others go on; failed ones
//    are run again only with --retry-failed, interrupted ones always. SIGINT/SIGTERM: each
//    running child is sent it once (it stops after its frame, outputs kept partial), no
//    new one starts; a second signal is passed on too (the children end at once).
//    Slurm (--slurm): DIR/slurm/sweep.sbatch, a job array of the variants to run, one per
//    task (`esim dataset run DIR <index>`), --mem and --time from a measured run of the
//    scene (the largest peak memory and wall time of the complete variants; when none is
//    complete, the first variant to run is run first to measure it: with --submit as its own
//    job at the partition's default limits, without it here), --cpus-per-task from the
//    scene's threads; with --submit it is submitted and waited for (Ctrl-C: scancel).
// 4. After each variant its result.json and the manifest are written (dataset.h).
// Exit: 0 every variant complete (--slurm without --submit: the script written), 1 some
// failed or interrupted (or not run), 2 bad input.
#pragma once

#include <functional>
#include <string>
#include <vector>

namespace esim::app {

struct SweepOptions {
  std::string spec;                  // the sweep file
  std::string outDir;                // DIR
  int workers = 1;                   // local: variants at once
  bool retryFailed = false;          // run failed variants again
  std::vector<std::string> runArgs;  // more `esim run` options (after the file's run_options)
  bool dryRun = false;               // expand, check and list; write nothing
  bool quiet = false;
  // Slurm
  bool slurm = false;                   // write the job-array script instead of running here
  bool submit = false;                  // sbatch it and wait
  int memMb = 0;                        // per task; 0 = measured
  int timeMin = 0;                      // per task; 0 = measured
  int cpus = 0;                         // per task; 0 = from the scene's threads
  int maxParallel = 0;                  // the array's %N throttle; 0 = none
  std::vector<std::string> sbatchArgs;  // more #SBATCH lines, e.g. --partition=gpu
};

// checks extra `esim run` options (throws Error naming the bad one); the command gives
// one that parses them with `esim run`'s own definition
using RunOptionsCheck = std::function<void(const std::vector<std::string>&)>;

// `esim sweep`; returns the exit code, throws Error for bad input
int runSweep(const SweepOptions& options, const RunOptionsCheck& checkRunOptions);

// --sbatch-arg values, checked before anything is written: one sbatch option each, no line
// break or control character (one ended the #SBATCH line and put the rest into the script as
// a command), and none of the options the script sets itself (--array, --output, --ntasks,
// --cpus-per-task, --mem*, --time: each names the esim option to give instead). Throws Error.
void checkSbatchArgs(const std::vector<std::string>& args);

// `esim dataset run DIR VARIANT` (what each Slurm task runs): runs one variant (its id or
// index) of a prepared sweep folder unless it is complete, writes its result and the
// manifest; 0 complete, 1 not
int runSweepVariant(const std::string& dir, const std::string& variant, bool retryFailed);

// the `esim` executable that runs the variants (this process's, /proc/self/exe)
std::string esimExecutable();

}  // namespace esim::app
