// bench_common.h - what the `esim bench` commands share: option parsing, the default scene,
// and the --csv table written whole.
#pragma once

#include <sstream>
#include <string>
#include <vector>

namespace esim::app {

// "a,b,c" -> {"a", "b", "c"} (empty items dropped)
std::vector<std::string> splitList(const std::string& text);

// "1013,20000" -> {1013, 20000}: node counts in [27, 5e6]; throws esim::Error naming
// `command`'s option (--sizes unless given) and the bad item
std::vector<int> parseNodeCounts(const std::string& text, const std::string& command,
                                 const std::string& option = "--sizes");

// a comma list of integers in [lo, hi] (e.g. "5,95"); throws esim::Error "OPTION: 'ITEM' is
// not an integer in [lo, hi] (expected EXAMPLE)", or "OPTION is empty"
std::vector<int> parseIntegerList(const std::string& text, const std::string& option, long lo,
                                  long hi, const std::string& example);
// ... of numbers in [lo, hi]
std::vector<double> parseNumberList(const std::string& text, const std::string& option, double lo,
                                    double hi, const std::string& example);

// The scene file of a bench: `path` as given; the bench's default (`defaultPath`, relative
// to the source folder, e.g. scenarios/slab_cut.yaml) when not in the working folder is
// looked for above the esim executable, then in the source tree it was built from. Throws
// esim::Error naming --scenario when the default is nowhere (a path given is left to the
// scenario loader's message).
std::string benchScenarioPath(const std::string& path, const std::string& defaultPath);

// A bench's --csv table, written whole or not at all. The constructor checks that FILE can
// be written (a probe file beside it, removed again), so a bad path fails before the bench
// runs; rows are kept in memory; commit() writes them to a temporary file beside FILE and
// renames it to FILE. A bench that stops before commit() (bad input found later, an error,
// an interruption) leaves FILE as it was: an earlier table is never truncated or left half
// written. An empty path is no table (false).
class CsvOutput {
 public:
  // throws esim::Error "--csv: cannot write 'FILE' (...)" (a folder, a missing folder, no
  // permission)
  CsvOutput(std::string path, const std::string& header);
  explicit operator bool() const { return !path_.empty(); }
  std::ostringstream& out() { return rows_; }  // the rows after the header
  // writes and renames (once); throws esim::Error (Run kind) when that fails, FILE untouched
  void commit();

 private:
  std::string path_;
  std::ostringstream rows_;
};

}  // namespace esim::app
