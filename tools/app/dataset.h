// dataset.h - the folder of a sweep (`esim sweep SPEC -o DIR`) and its records.
//
//   DIR/sweep.yaml                 the sweep file as given (a copy)
//   DIR/sweep.json                 what the sweep is: name, base, seed, run options, and
//                                  every variant's id and values (what a Slurm task reads)
//   DIR/manifest.jsonl             one line per variant, in order (below)
//   DIR/runs/<id>/scenario.yaml    the variant, fully resolved (esim run's input)
//   DIR/runs/<id>/run/             the run's folder (run.partial/ while it runs or after a
//                                  failure), as `esim run -o` writes it
//   DIR/runs/<id>/log.txt          the run's output (summary, errors)
//   DIR/runs/<id>/result.json      how the run ended, with the hash of every file it wrote
//   DIR/slurm/                     the job-array script and the tasks' logs (--slurm)
// A manifest line: id, index, values (the grid and random keys), status (complete, failed,
// interrupted, pending), exit_code, message, wall_s, cpu_s (the run's user + system CPU
// time), frames, peak_rss_mb, warnings (timing.json's), host, slurm_job, finished (UTC),
// video (its path), video_xxh3, frames_xxh3 (hashes.json's hash over all frames),
// labels_xxh3 (over the files under labels/, null when the run wrote none) and files: every
// file of runs/<id>/ the run made, recursively (scenario.yaml and everything in run/), path
// relative to DIR -> xxh3-64 of its bytes (16 hex digits); memory_retry ({workers, message})
// when a local sweep ran the variant again alone after it stopped for memory beside others.
// The manifest is rewritten whole (a new file renamed over the old, under an flock on
// DIR/.lock) from sweep.json and the result.json files each time a variant ends, by
// whichever process ran it: the local sweep, or a Slurm task.
#pragma once

#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace esim::app {

namespace dataset {
inline std::filesystem::path variantDir(const std::filesystem::path& dir, const std::string& id) {
  return dir / "runs" / id;
}
inline std::filesystem::path runDir(const std::filesystem::path& dir, const std::string& id) {
  return variantDir(dir, id) / "run";
}
// the sweep folder DIR when run is DIR/runs/<id>/run of a sweep (DIR holds manifest.jsonl),
// else ""
inline std::filesystem::path sweepOfRun(const std::filesystem::path& run) {
  std::error_code ec;
  std::filesystem::path p = std::filesystem::absolute(run, ec).lexically_normal();
  if (p.filename().empty()) p = p.parent_path();  // "run/"
  const std::filesystem::path dir = p.parent_path().parent_path().parent_path();
  if (p.filename() != "run" || p.parent_path().parent_path().filename() != "runs" ||
      !std::filesystem::is_regular_file(dir / "manifest.jsonl", ec))
    return {};
  return dir;
}
}  // namespace dataset

// xxh3-64 (seed 0) of a file's bytes as 16 hex digits; throws Error if it cannot be read
std::string hashFile(const std::filesystem::path& path);

// every regular file under root, recursively, as path relative to base -> hashFile;
// sorted by path
nlohmann::json hashTree(const std::filesystem::path& root, const std::filesystem::path& base);

// DIR/sweep.json, checked by checkSweepJson (throws Error, input kind, when DIR holds none)
nlohmann::json readSweepJson(const std::filesystem::path& dir);

// what the sweep and dataset commands read of a sweep.json, checked: an object whose
// variants are {id, index, values} with the ids and indices esim sweep gives (v0000, 0, ...)
// and run_options a list of strings; throws Error "PATH: variants[1].id = ...; expected
// ..." (an edited id such as "../../x" led `esim dataset run` to write outside the sweep, an
// edited type was an internal error)
void checkSweepJson(const nlohmann::json& j, const std::filesystem::path& path);

// runs/<id>/result.json, or null when there is none or it is torn or malformed (a status
// that is not a string, files that are not {path: hash}): the variant counts as not run
nlohmann::json readResult(const std::filesystem::path& dir, const std::string& id);
// writes runs/<id>/result.json (a new file renamed into place)
void writeResult(const std::filesystem::path& dir, const std::string& id,
                 const nlohmann::json& result);

// the esim build that made a variant, as one printable line (buildInfoLine of a manifest
// line's or result's esim_build, the run's timing.json "build"); "an esim that did not
// record its build" for results from before it did
std::string variantBuildLine(const nlohmann::json& line);
// the builds of a dataset's complete variants (variantBuildLine -> how many), as the sweep's
// end and `esim dataset verify` say them when there is more than one: "the complete variants
// were made by 2 builds of esim (...):\n    3 by esim ...\n    1 by esim ...\n"; "" for one
std::string datasetBuildsText(const std::map<std::string, int>& builds);

// the manifest's lines as of now (sweep.json's variants with their results)
std::vector<nlohmann::json> manifestLines(const std::filesystem::path& dir);
// rewrites DIR/manifest.jsonl from sweep.json and the results (under DIR/.lock)
void writeManifest(const std::filesystem::path& dir);

// `esim dataset verify DIR`: every file of every complete variant re-hashed against the
// manifest; a file changed, missing, or not in the manifest (in run/ or beside it in the
// variant's folder, but the sweep's log.txt and result.json; or in runs/ beside the
// variants' folders) is a problem
struct VerifyReport {
  int variants = 0, complete = 0, notComplete = 0;
  int filesChecked = 0;
  std::vector<std::string> problems;  // "runs/v0003/run/video.mp4: ..." one per file
  // the esim builds that made the complete variants, each with how many (not a problem: a
  // dataset of two builds is said, the files still match)
  std::map<std::string, int> builds;
};
VerifyReport verifyDataset(const std::filesystem::path& dir);

}  // namespace esim::app
