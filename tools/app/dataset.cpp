// dataset.cpp - the records of a sweep folder: file hashes, results, the manifest and its
// verification (see dataset.h).
#include "tools/app/dataset.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>
#include <xxhash.h>

#include <algorithm>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "render/image_hash.h"
#include "sim/core_error.h"
#include "sim/message_text.h"
#include "tools/app/build_info.h"
#include "tools/app/json_text.h"
#include "tools/app/run_output.h"
#include "tools/app/sweep_spec.h"

namespace esim::app {

namespace fs = std::filesystem;

namespace {

std::string readText(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  if (!in) throw Error(p.string() + ": cannot be read", ErrorKind::Run);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

nlohmann::json readJson(const fs::path& p) {
  try {
    return nlohmann::json::parse(readText(p));
  } catch (const nlohmann::json::exception& e) {
    throw Error(p.string() + ": not valid JSON (" + printableInMessage(e.what()) + ")");
  }
}

// holds an exclusive flock on DIR/.lock while alive (flock works on NFS since Linux 2.6.12)
class ManifestLock {
 public:
  explicit ManifestLock(const fs::path& dir) {
    fd_ = ::open((dir / ".lock").c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd_ >= 0)
      while (::flock(fd_, LOCK_EX) != 0 && errno == EINTR) {
      }
  }
  ~ManifestLock() {
    if (fd_ >= 0) ::close(fd_);
  }
  ManifestLock(const ManifestLock&) = delete;
  ManifestLock& operator=(const ManifestLock&) = delete;

 private:
  int fd_ = -1;
};

}  // namespace

std::string hashFile(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(path.string() + ": cannot be read", ErrorKind::Run);
  XXH3_state_t* state = XXH3_createState();
  XXH3_64bits_reset(state);
  std::vector<char> buf(1 << 20);
  while (in) {
    in.read(buf.data(), static_cast<std::streamsize>(buf.size()));
    if (in.gcount() > 0) XXH3_64bits_update(state, buf.data(), static_cast<size_t>(in.gcount()));
  }
  const bool ok = in.eof();
  const std::uint64_t h = XXH3_64bits_digest(state);
  XXH3_freeState(state);
  if (!ok) throw Error(path.string() + ": read failed", ErrorKind::Run);
  return hashToHex(h);
}

nlohmann::json hashTree(const fs::path& root, const fs::path& base) {
  std::vector<fs::path> files;
  std::error_code ec;
  if (fs::is_directory(root, ec))
    for (auto it = fs::recursive_directory_iterator(root); it != fs::recursive_directory_iterator();
         ++it)
      if (it->is_regular_file()) files.push_back(it->path());
  std::sort(files.begin(), files.end());
  nlohmann::json out = nlohmann::json::object();
  for (const auto& f : files) out[f.lexically_relative(base).generic_string()] = hashFile(f);
  return out;
}

nlohmann::json readSweepJson(const fs::path& dir) {
  const fs::path p = dir / "sweep.json";
  std::error_code ec;
  if (!fs::is_regular_file(p, ec))
    throw Error(dir.string() + ": not a sweep folder (no sweep.json; esim sweep SPEC -o " +
                dir.string() + " makes one)");
  const nlohmann::json j = readJson(p);
  checkSweepJson(j, p);
  return j;
}

void checkSweepJson(const nlohmann::json& j, const fs::path& path) {
  const std::string file = path.string() + ": ";
  const std::string edited = " (sweep.json is esim sweep's record: an edited or foreign file)";
  ESIM_VERIFY(j.is_object(), file + "expected a JSON object" + edited);
  const auto variants = j.find("variants");
  ESIM_VERIFY(variants != j.end() && variants->is_array(),
              file + "variants: expected a list of {id, index, values}" + edited);
  for (size_t i = 0; i < variants->size(); ++i) {
    const nlohmann::json& v = (*variants)[i];
    const std::string at = file + "variants[" + std::to_string(i) + "]";
    ESIM_VERIFY(v.is_object(), at + ": expected an object {id, index, values}" + edited);
    const auto id = v.find("id");
    const bool idOk = id != v.end() && id->is_string() &&
                      id->get_ref<const std::string&>() == variantId(i, variants->size());
    ESIM_VERIFY(idOk,
                at + ".id = " + (id == v.end() ? std::string("(missing)") : jsonInMessage(*id)) +
                    "; expected \"" + variantId(i, variants->size()) + "\"" + edited);
    const auto index = v.find("index");
    ESIM_VERIFY(index != v.end() && index->is_number_integer() &&
                    index->get<long long>() == static_cast<long long>(i),
                at + ".index: expected " + std::to_string(i) + edited);
    ESIM_VERIFY(v.contains("values") && v["values"].is_object(),
                at + ".values: expected an object {field: value}" + edited);
  }
  if (const auto opts = j.find("run_options"); opts != j.end()) {
    bool ok = opts->is_array();
    if (ok)
      for (const auto& o : *opts) ok = ok && o.is_string();
    ESIM_VERIFY(ok, file + "run_options: expected a list of strings" + edited);
  }
}

namespace {
// a result.json as runVariant writes it: an object whose status, message, id, files and
// numbers have their types (anything else, torn or edited, counts as not run)
bool wellFormedResult(const nlohmann::json& r) {
  if (!r.is_object() || !r.contains("status") || !r["status"].is_string()) return false;
  for (const char* key : {"id", "message", "video"})
    if (r.contains(key) && !r[key].is_string() && !r[key].is_null()) return false;
  for (const char* key : {"wall_s", "cpu_s", "peak_rss_mb", "frames", "exit_code"})
    if (r.contains(key) && !r[key].is_number() && !r[key].is_null()) return false;
  if (r.contains("files")) {
    if (!r["files"].is_object()) return false;
    for (const auto& h : r["files"])
      if (!h.is_string()) return false;
  }
  return true;
}
}  // namespace

nlohmann::json readResult(const fs::path& dir, const std::string& id) {
  const fs::path p = dataset::variantDir(dir, id) / "result.json";
  std::error_code ec;
  if (!fs::is_regular_file(p, ec)) return nullptr;
  try {
    nlohmann::json r = nlohmann::json::parse(readText(p));
    return wellFormedResult(r) ? r : nlohmann::json();
  } catch (const std::exception&) {
    return nullptr;  // a torn or foreign file: the variant counts as not run
  }
}

void writeResult(const fs::path& dir, const std::string& id, const nlohmann::json& result) {
  writeFileAtomic(dataset::variantDir(dir, id) / "result.json", jsonText(result, 2) + "\n");
}

std::string variantBuildLine(const nlohmann::json& line) {
  const std::optional<BuildInfo> b =
      buildInfoFromJson(line.is_object() ? line.value("esim_build", nlohmann::json()) : nullptr);
  return b ? printableInMessage(buildInfoLine(*b), 200) : "an esim that did not record its build";
}

std::string datasetBuildsText(const std::map<std::string, int>& builds) {
  if (builds.size() < 2) return "";
  std::string text = "the complete variants were made by " + std::to_string(builds.size()) +
                     " builds of esim (the manifest's \"esim_build\"):\n";
  for (const auto& [build, n] : builds) text += "    " + std::to_string(n) + " by " + build + "\n";
  return text;
}

std::vector<nlohmann::json> manifestLines(const fs::path& dir) {
  const nlohmann::json sweep = readSweepJson(dir);
  std::vector<nlohmann::json> lines;
  for (const auto& v : sweep.at("variants")) {
    const std::string id = v.at("id");
    nlohmann::json line = {{"id", id}, {"index", v.at("index")}, {"values", v.at("values")}};
    const nlohmann::json r = readResult(dir, id);
    if (r.is_object()) {
      for (auto it = r.begin(); it != r.end(); ++it)
        if (!line.contains(it.key())) line[it.key()] = it.value();
    } else {
      line["status"] = "pending";
    }
    lines.push_back(std::move(line));
  }
  return lines;
}

void writeManifest(const fs::path& dir) {
  ManifestLock lock(dir);
  std::string text;
  for (const auto& line : manifestLines(dir)) text += jsonText(line) + "\n";
  writeFileAtomic(dir / "manifest.jsonl", text);
}

VerifyReport verifyDataset(const fs::path& dir) {
  const fs::path manifest = dir / "manifest.jsonl";
  std::error_code ec;
  if (!fs::is_regular_file(manifest, ec))
    throw Error(dir.string() + ": no manifest.jsonl (not a sweep folder made by esim sweep)");
  VerifyReport rep;
  std::set<std::string> ids;     // of the complete variants so far
  std::set<std::string> listed;  // every id a line names, whatever its status
  std::istringstream in(readText(manifest));
  int lineNo = 0;
  for (std::string text; std::getline(in, text);) {
    ++lineNo;
    if (text.empty()) continue;
    nlohmann::json line;
    try {
      line = nlohmann::json::parse(text);
    } catch (const nlohmann::json::exception&) {
      rep.problems.push_back("manifest.jsonl:" + std::to_string(lineNo) + ": not valid JSON");
      continue;
    }
    const std::string at = "manifest.jsonl:" + std::to_string(lineNo) + ": ";
    // a line is an object whose status, id and files have the types esim sweep writes: an
    // edited line was an internal error (a JSON type error, exit 4)
    if (!line.is_object()) {
      rep.problems.push_back(at + "expected a JSON object (a variant), got " + jsonInMessage(line));
      continue;
    }
    ++rep.variants;
    if (const auto named = line.find("id"); named != line.end() && named->is_string())
      listed.insert(named->get<std::string>());
    const auto status = line.find("status");
    if (status == line.end() || !status->is_string()) {
      rep.problems.push_back(at + "status: expected a string (complete, failed, ...)");
      continue;
    }
    if (status->get<std::string>() != "complete") {
      ++rep.notComplete;
      continue;
    }
    ++rep.complete;
    ++rep.builds[variantBuildLine(line)];
    const auto idField = line.find("id");
    const std::string id =
        idField != line.end() && idField->is_string() ? idField->get<std::string>() : "";
    if (id.empty() || id.find('/') != std::string::npos || id.find("..") != std::string::npos) {
      rep.problems.push_back(
          at + "bad id " +
          (idField == line.end() ? std::string("(missing)") : jsonInMessage(*idField)));
      continue;
    }
    if (!ids.insert(id).second) {
      rep.problems.push_back(at + "id " + id + " is listed a second time");
      continue;
    }
    const nlohmann::json files = line.value("files", nlohmann::json::object());
    if (!files.is_object()) {
      rep.problems.push_back(at + "files: expected an object {path: xxh3}, got " +
                             jsonInMessage(files));
      continue;
    }
    // what is on disk now: scenario.yaml, everything under run/, and anything else in the
    // variant's folder but the sweep's own log.txt and result.json (an added file there was
    // not noticed)
    std::map<std::string, fs::path> onDisk;
    const fs::path vdir = dataset::variantDir(dir, id);
    const fs::path run = dataset::runDir(dir, id);
    if (fs::is_directory(vdir, ec))
      for (const fs::directory_entry& e : fs::directory_iterator(vdir, ec)) {
        const std::string name = e.path().filename().string();
        if (e.path() == run || name == "log.txt" || name == "result.json") continue;
        onDisk[e.path().lexically_relative(dir).generic_string()] = e.path();
      }
    if (fs::is_directory(run, ec))
      for (auto it = fs::recursive_directory_iterator(run);
           it != fs::recursive_directory_iterator(); ++it)
        if (it->is_regular_file())
          onDisk[it->path().lexically_relative(dir).generic_string()] = it->path();
    for (auto it = files.begin(); it != files.end(); ++it) {
      const std::string rel = it.key();
      if (!it.value().is_string()) {
        rep.problems.push_back(at + "files[\"" + rel + "\"]: expected an xxh3 string, got " +
                               jsonInMessage(it.value()));
        onDisk.erase(rel);
        continue;
      }
      const std::string want = it.value().get<std::string>();
      auto found = onDisk.find(rel);
      if (found == onDisk.end()) {
        const fs::path relPath(rel);
        const bool inside =
            rel.rfind(dataset::variantDir(fs::path(), id).generic_string() + "/", 0) == 0 &&
            rel.find("..") == std::string::npos && !relPath.is_absolute();
        rep.problems.push_back(inside ? rel + ": missing (the manifest lists it)"
                                      : at + "files: '" + rel +
                                            "' is outside the variant's "
                                            "folder (an edited manifest)");
        continue;
      }
      ++rep.filesChecked;
      std::string got;
      try {
        got = hashFile(found->second);
      } catch (const Error& e) {
        rep.problems.push_back(rel + ": " + e.what());
        onDisk.erase(found);
        continue;
      }
      if (got != want)
        rep.problems.push_back(rel + ": changed (xxh3 " + got + ", the manifest has " + want + ")");
      onDisk.erase(found);
    }
    for (const auto& [rel, path] : onDisk)
      rep.problems.push_back(rel + ": not in the manifest (added after the run)");
  }
  // runs/ holds the variants' folders only: anything else was added beside them
  std::set<std::string> extra;
  if (fs::is_directory(dir / "runs", ec))
    for (const fs::directory_entry& e : fs::directory_iterator(dir / "runs", ec))
      if (!listed.count(e.path().filename().string()))
        extra.insert("runs/" + e.path().filename().string());
  for (const std::string& rel : extra)
    rep.problems.push_back(rel + ": not in the manifest (no variant has this name)");
  return rep;
}

}  // namespace esim::app
