// run_output.h - the output folder of a run: never destroys what the run did not create.
//
// A run writes into DIR.partial/ (marked by a file `.esim-run`) and renames it to DIR/ only
// when it completed. Before anything is computed, prepare() refuses (Input error, nothing
// touched):
//   - DIR that is a file, or a folder that is not empty and does not hold an earlier ESim
//     run (its `.esim-run` marker, or timing.json + scenario.yaml + summary.txt);
//   - a folder holding an earlier run, unless overwrite is set (then it is replaced, at the
//     end, by the complete run);
//   - DIR.partial/ that exists and is not an ESim run's;
//   - a location whose parent cannot be created or written.
// A run that fails or is interrupted stays DIR.partial/ with what it wrote (its reports say
// "complete": false); a set-up that fails before the first frame removes DIR.partial/, which
// it created itself.
// One run at a time: create() holds an exclusive flock on DIR.partial/ until the RunOutput
// goes (the kernel releases it if the process dies), and checks DIR again under it. A second
// run into the same folder is refused (Input error), at once when it starts while the first
// writes, else at its create(); two runs used to write the same DIR.partial/ together, one
// committing a video that did not play.
#pragma once

#include <filesystem>
#include <string>

namespace esim::app {

// An exclusive flock on a folder, held while the object lives (the kernel drops it when the
// process dies): one esim run per output folder, one esim sweep per sweep folder.
class FolderLock {
 public:
  FolderLock() = default;
  // locks the existing folder dir; false when another process holds it; throws Error (Input)
  // naming `what` when it cannot be opened
  bool tryLock(const std::filesystem::path& dir, const std::string& what);
  int fd() const { return fd_; }  // -1 when none is held
  void release();
  ~FolderLock() { release(); }
  FolderLock(const FolderLock&) = delete;
  FolderLock& operator=(const FolderLock&) = delete;

 private:
  int fd_ = -1;
};

class RunOutput {
 public:
  // checks the location (see above); throws Error naming the folder and the remedy
  RunOutput(std::filesystem::path dir, bool overwrite);

  // creates DIR.partial/ with its marker, locked (an earlier run's DIR.partial/ emptied);
  // throws Error when another run holds it, or when DIR changed since the constructor's
  // checks (another run completed there)
  void create();

  // the folder being written (DIR.partial/)
  const std::filesystem::path& partial() const { return partial_; }
  // the final folder (DIR/)
  const std::filesystem::path& final() const { return dir_; }

  // the run completed: DIR.partial/ becomes DIR/ (an earlier run there is replaced)
  void commit();

  // set-up failed before the first frame: remove DIR.partial/ (ours)
  void discard();

  RunOutput(const RunOutput&) = delete;
  RunOutput& operator=(const RunOutput&) = delete;

 private:
  void checkFinal() const;    // DIR: a new or empty folder, or an earlier run with overwrite
  void checkPartial() const;  // DIR.partial: empty, or an earlier run's output and nothing else

  std::filesystem::path dir_, partial_;
  bool overwrite_ = false;
  FolderLock lock_;  // on DIR.partial/, taken by create()
};

// true when the folder holds an ESim run (complete or partial)
bool isEsimRunFolder(const std::filesystem::path& dir);

// true for prefix + 5 or more digits + suffix: the numbered files of runs and reports
// (frame_00030.png, diff_frame_00004.png)
bool isNumberedName(const std::string& name, const std::string& prefix, const std::string& suffix);

// the first entry of a run's folder that `esim run` does not write (its files, frames/,
// fields/, labels/, and compare/ of esim compare's former default report), as a relative
// path ("notes.txt", "plots/"); "" when there is none. --overwrite and an earlier partial
// output are replaced only without one: a user's file put into a run folder is never deleted.
std::string foreignEntry(const std::filesystem::path& dir);

// `esim run`'s folder without -o: out/<name>, the scenario's name (free text, a title) made a
// single folder name: every character but letters, digits, '-', '_' and '.' becomes '_', so
// do leading dots ("", "." and ".." included: never out/ itself, a parent, or an absolute
// path; "unnamed" when empty)
std::filesystem::path defaultRunFolder(const std::string& scenarioName);

// A folder of results that a command writes its named files into, replacing them (esim bench
// accuracy --out, render-sample --out, compare --report): created with its parents when
// missing, and held in `lock` (flock) while the command writes it: two commands into one
// folder interleaved their files. Throws Error (Input) naming `option` and the path when it
// is a file, cannot be created or another esim holds it, before anything is computed.
void createOutputFolder(const std::filesystem::path& dir, const std::string& option,
                        FolderLock& lock);

// writes text to path whole: through a temporary file beside it (PATH.tmp<pid>), renamed into
// place; throws Error (Run kind) when that fails, path untouched and the temporary removed
void writeFileAtomic(const std::filesystem::path& path, const std::string& text);

}  // namespace esim::app
