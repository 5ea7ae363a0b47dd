// run.cpp - one run of a scenario (see run.h).
//
// Outline:
//   ---- set-up ----        scenario, output folder, mesh, simulation, renderer
//   ---- frame outputs ---- video, hashes, PNGs and VTU fields of each frame
//   ---- reports ----       timing.json's extra block, hashes.json, summary.txt
//   ---- the run ----       runScenario: set-up, frame loop, reports, rename
#include "tools/app/run.h"

#include <malloc.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <memory>
#include <mutex>
#include <new>
#include <optional>
#include <sstream>
#include <system_error>
#include <thread>

#include "render/image_hash.h"
#include "render/image_png.h"
#include "render/renderer.h"
#include "render/video_encoder.h"
#include "render/view_check.h"
#include "sim/core_error.h"
#include "sim/io/scenario.h"
#include "sim/io/vtu.h"
#include "sim/message_text.h"
#include "sim/simulation.h"
#include "tools/app/build_info.h"
#include "tools/app/dataset.h"
#include "tools/app/exit_codes.h"
#include "tools/app/json_text.h"
#include "tools/app/memory_room.h"
#include "tools/app/plot_script.h"
#include "tools/app/run_config.h"
#include "tools/app/run_labels.h"
#include "tools/app/run_output.h"
#include "tools/app/run_report.h"
#include "tools/app/thread_priority.h"

namespace esim::app {

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

std::atomic<bool> gStop{false};
// the first SIGINT/SIGTERM stops the run: between frames, or inside a frame at its next
// checkInterrupt() (a stage, an explicit sub-step, a patch of prefetched columns, a phase of
// a rebuild: the longest wait is one factorization); a second one ends the process at once
// with the signal's default action
extern "C" void onSignal(int sig) {
  if (gStop.exchange(true)) {
    std::signal(sig, SIG_DFL);
    std::raise(sig);
  }
}

// above this the run's temperatures are outside what the model describes (no charring,
// no ablation): the summary and timing.json say so [C]
constexpr double kImplausibleTemperatureC = 300.0;

double secondsSince(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// peak resident memory of this process so far [MB]
double peakRssMb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_maxrss / 1024.0;  // ru_maxrss is in kB on Linux
}

std::string numbered(const char* prefix, int frame, const char* ext) {
  std::ostringstream name;
  name << prefix << std::setw(5) << std::setfill('0') << frame << ext;
  return name.str();
}

// ---- set-up ----

struct Setup {
  Scenario scenario;
  int frames = 0;
  int fieldsEvery = 0;
  bool video = false;
  LabelOutputOptions labels;
  int nodes = 0, tets = 0;
  double meshS = 0, setupS = 0, rssAfterSetupMb = 0;
  std::unique_ptr<Simulation> sim;
  std::unique_ptr<Renderer> renderer;  // null when nothing is drawn
  std::string viewWarning;             // the camera sees no tissue or misses the tool ("": no)
};

// a camera that sees none of the tissue at the start: the video would be the background
// alone (render/view_check.h; the tissue does not move, only deforms, so it never would); or
// whose view misses the tool's tip in most of the run's frames (the cut happens off screen),
// or for which the tissue hides the tool in most of them (seen from below or through a side)
std::string viewWarning(const RenderOptions& o, Simulation& sim, const Scenario& sc, int frames) {
  const SurfaceSnapshot snap = sim.snapshot(sc.look.displacementScale);
  const ViewCheck v = checkView(o, snap);
  const auto mm = [](const Vec3& p) {
    char b[96];
    std::snprintf(b, sizeof b, "[%.1f, %.1f, %.1f] mm", p[0] * 1e3, p[1] * 1e3, p[2] * 1e3);
    return std::string(b);
  };
  const std::string eye = "camera.eye_m " + mm(sc.camera.eyeM);
  const std::string camera = eye + ", camera.target_m " + mm(sc.camera.targetM) +
                             ", camera.fov_deg " + std::to_string(std::lround(sc.camera.fovDeg));
  if (v.eyeInside)
    return eye +
           " is inside the tissue, whose surface is drawn from outside only: the frames "
           "show the background; put the eye outside the tissue";
  if (!v.seesSurface)
    return "the camera sees none of the tissue (" + camera +
           "): the frames show the background; point camera.target_m at the tissue";
  // the tool's tip at each frame's time
  const ToolPath& path = sim.config().toolPath;
  int outside = 0;
  for (int f = 0; f < frames; ++f) {
    const Vec3 tip = path.positionAt(f / sc.time.fps);
    outside += !inView(o, {tip[0], tip[1], tip[2]});
  }
  if (2 * outside > frames)
    return "the tool's tip is outside the camera's view in " + std::to_string(outside) + " of " +
           std::to_string(frames) + " frames (" + camera +
           "): the video shows little of the cut; point camera.target_m at the tool's path";
  // the tool hidden by the tissue (as it is at the start) in up to 60 of the frames: every
  // point of its axis, from the tip (in the tissue while it cuts) to the electrode's length,
  // 1 mm apart, out of view or behind the surface
  const int checked = std::min(frames, 60);
  const double lengthM = sim.config().electrode.lengthM;
  const int points = 1 + static_cast<int>(std::ceil(lengthM / 0.001));
  int hidden = 0;
  for (int k = 0; k < checked; ++k) {
    const double t = (checked > 1 ? k * (frames - 1.0) / (checked - 1) : 0.0) / sc.time.fps;
    const Vec3 axis = path.orientationAt(t) * Vec3::UnitZ();
    bool seen = false;
    for (int i = 0; i < points && !seen; ++i) {
      const Vec3 q = path.positionAt(t) + (lengthM * i / (points - 1)) * axis;
      seen = inView(o, {q[0], q[1], q[2]}) && !hiddenBySurface(o, snap, {q[0], q[1], q[2]});
    }
    hidden += !seen;
  }
  if (2 * hidden <= checked) return "";
  return "the tissue hides the tool in " + std::to_string(hidden) + " of " +
         std::to_string(checked) +
         " frames checked (its axis from the tip up, as the tissue is "
         "at the start; " +
         camera +
         "): the video shows little of the cut; put camera.eye_m on the tool's side of the "
         "tissue";
}

// the mesh, phases and renderer of a loaded scenario; throws Error (nothing written)
Setup setUp(const RunOptions& opt, Scenario scenario) {
  Setup s;
  s.scenario = std::move(scenario);
  const Scenario& sc = s.scenario;
  s.frames = opt.frames > 0 ? opt.frames : frameCount(sc);
  s.fieldsEvery = opt.fieldsEvery >= 0 ? opt.fieldsEvery : sc.output.fieldsEvery;
  s.video = sc.output.video && !opt.noVideo;
  s.labels.enabled = opt.labels || opt.labelsPreview;
  s.labels.preview = opt.labelsPreview;
  checkRunnable(sc, false, opt.noVideo);  // before the mesh, which can take seconds
  if (s.labels.enabled) validateRenderOptions(makeRenderOptions(sc));
  if (s.labels.preview) validateVideoRate(sc.time.fps);
  const SimulationConfig config = makeSimulationConfig(sc);
  // what only the mesh shows (a return electrode off the tissue, a singular model) is the
  // scenario's: its errors name the file as the scenario checks do
  try {
    const auto t0 = Clock::now();
    // Mesh_3 of a surface file takes seconds to minutes (about 500 s for 1e7 tets here) and
    // says nothing while it runs: say what it does first
    if (!opt.quiet && sc.mesh.source == MeshSource::File) {
      const ScenarioMeshFile& f = sc.mesh.file;
      std::fprintf(stderr, "esim: meshing %s (mesh.file.cell_size_m %g m",
                   printablePath(f.path).c_str(), f.cellSizeM);
      if (f.refine.enabled)
        std::fprintf(stderr, ", refine.cell_size_m %g m near the cut", f.refine.cellSizeM);
      std::fprintf(stderr, ")\n");
    }
    TetMesh mesh = buildMesh(sc);
    s.meshS = secondsSince(t0);
    s.nodes = mesh.numNodes();
    s.tets = mesh.numTets();
    // a large mesh's set-up (the solvers' factorizations) takes minutes: say what it does
    if (!opt.quiet && (s.meshS > 1.0 || s.nodes >= 20000))
      std::fprintf(stderr, "esim: mesh of %d nodes, %d tets in %.1f s; setting up the phases\n",
                   s.nodes, s.tets, s.meshS);
    const auto t1 = Clock::now();
    s.sim = std::make_unique<Simulation>(std::move(mesh), config);
    s.setupS = secondsSince(t1);
    // what the set-up found (a piece off the return electrode, a tool path under the
    // surface), before a run of minutes: even with -q, as the summary will repeat it
    for (const std::string& w : s.sim->warnings())
      std::fprintf(stderr, "esim: warning: %s\n", printableMessage(w).c_str());
  } catch (const Error& e) {
    rethrowNamingScenario(e, sc);
  }
  s.rssAfterSetupMb = peakRssMb();
  if (s.video || sc.output.pngEvery > 0 || sc.output.hashes || s.labels.enabled)
    s.renderer = std::make_unique<Renderer>(makeRenderOptions(sc));
  if (s.renderer) {
    s.viewWarning = viewWarning(s.renderer->options(), *s.sim, sc, s.frames);
    if (!s.viewWarning.empty())  // (even with -q: it says the video will show nothing)
      std::fprintf(stderr, "esim: warning: %s\n", printableMessage(s.viewWarning).c_str());
  }
  return s;
}

// ---- frame outputs ----

// Fault injection for the tests of the loop's failure paths, which a real fault reaches
// only by chance (memory running out in the middle of a run): ESIM_FAULT=bad_alloc@N makes
// frame N throw std::bad_alloc after its physics, as if an allocation had failed;
// ESIM_FAULT=draw@N makes drawing frame N fail (on the drawing thread when there is one);
// ESIM_FAULT=video_close@0 makes closing the video fail (a disk that fills at the end);
// ESIM_FAULT=alloc@N:MB makes frame N take MB megabytes more (see runLoop);
// ESIM_FAULT=thread@N makes frame N fail to start a thread;
// ESIM_FAULT=kill@N kills the process after frame N (see frameLoop). -1: none.
// (ESIM_FAULT=reader / reader_hang, read in sim/io/mesh_import.cpp, make the surface
// reader's child crash / never return.)
int injectedFaultFrame(const char* kind) {
  const char* spec = std::getenv("ESIM_FAULT");
  const std::string prefix = std::string(kind) + "@";
  if (!spec || std::string(spec).rfind(prefix, 0) != 0) return -1;
  return std::atoi(spec + prefix.size());
}

// the MB (1e6 bytes) of ESIM_FAULT=kind@N:MB (0 without it)
std::size_t injectedFaultMegabytes(const char* kind) {
  if (injectedFaultFrame(kind) < 0) return 0;
  const char* colon = std::strchr(std::getenv("ESIM_FAULT"), ':');
  return colon ? static_cast<std::size_t>(std::max(0L, std::atol(colon + 1))) : 0;
}

// output.encode: after keeps every frame raw until the end (and the labels' preview's, twice
// as wide, with --labels preview): refused up front (exit 2, nothing written) when the
// folder's disk has not that much free, with 64 MiB to spare for the rest
void checkSpoolRoom(const fs::path& dir, int frames, const VideoEncoder::Options& vo, bool video,
                    bool preview) {
  const double frameBytes = 3.0 * vo.width * vo.height * ((video ? 1 : 0) + (preview ? 2 : 0));
  const double needBytes = frameBytes * frames;
  std::error_code ec;
  const fs::space_info room = fs::space(dir, ec);
  if (ec) return;  // unknown: a write that fails says so, naming the file
  const double freeBytes = static_cast<double>(room.available);
  if (needBytes + 64.0 * 1048576 <= freeBytes) return;
  const auto mb = [](double bytes) { return std::to_string(std::llround(bytes / 1e6)); };
  throw Error("output.encode: after keeps the " + std::to_string(frames) +
              " frames raw until the video is encoded at the end (" +
              (video ? "" : "the labels' preview: ") + std::to_string((video ? 1 : 2) * vo.width) +
              " x " + std::to_string(vo.height) + " x 3 bytes each" +
              (video && preview ? ", and the labels' preview's twice that" : "") +
              "): " + mb(needBytes) + " MB on the disk of " +
              (dir.has_parent_path() ? dir.parent_path() : dir).string() + ", which has " +
              mb(freeBytes) +
              " MB free; set output.encode: during (encodes as the frames come) or free disk "
              "space");
}

class FrameOutputs {
 public:
  FrameOutputs(const Setup& s, const fs::path& dir, bool pipelined, bool physicsFirst)
      : s_(s), dir_(dir) {
    const Scenario& sc = s.scenario;
    VideoEncoder::Options vo;
    vo.path = (dir / "video.mp4").string();
    vo.width = sc.look.width;
    vo.height = sc.look.height;
    vo.fps = sc.time.fps;
    vo.crf = sc.output.crf;
    vo.preset = sc.output.preset;
    vo.reproducible = sc.output.reproducible;
    vo.deferred = sc.output.encode == "after";
    if (vo.deferred && (s.video || s.labels.preview))
      checkSpoolRoom(dir, s.frames, vo, s.video, s.labels.preview);
    if (s.video) {
      encoder_ = std::make_unique<VideoEncoder>();
      encoder_->open(vo);
    }
    if (s.labels.enabled)
      labels_ = std::make_unique<LabelWriter>(s.renderer->options(), dir, s.labels.preview, vo);
    if (sc.output.pngEvery > 0) fs::create_directories(dir / "frames");
    if (s.fieldsEvery > 0) fs::create_directories(dir / "fields");
    // --physics-first: llvmpipe's rasterizer threads (made with the renderer's context) and
    // the drawing thread, if any, at SCHED_IDLE
    if (s.renderer && pipelined)
      worker_ = std::thread([this, physicsFirst] {
        if (physicsFirst) idleThreads_ = idleThreadsNamed("llvmpipe-", true);
        drawLoop();
      });
    else if (s.renderer && physicsFirst)
      idleThreads_ = idleThreadsNamed("llvmpipe-", false);
  }

  // --physics-first: the threads moved to SCHED_IDLE (read once the loop is done)
  int idleThreads() const { return idleThreads_; }

  // a frame whose outputs are done: its record (render stages timed in) and when it was done
  struct Done {
    FrameRecord record;
    double doneUs = 0, renderStartUs = 0;  // from the loop's start
  };

  // a failure of the drawing thread: the frame it was drawing and the error
  struct DrawFailure {
    int frame;
    std::exception_ptr error;
  };

  // frame f's outputs. The VTU fields are written here; the drawing (render, hashes,
  // labels, PNGs, the encoder) is handed to the drawing thread when there is one
  // (pipelined: frame f is drawn while frame f+1 is simulated), else done here. Returns
  // the frames whose outputs finished meanwhile, in order. Throws DrawFailure when the
  // drawing of an earlier frame failed, or what the fields' writing throws.
  std::vector<Done> add(int f, Simulation& sim, const FrameRecord& physics) {
    const Scenario& sc = s_.scenario;
    if (s_.fieldsEvery > 0 && f % s_.fieldsEvery == 0)
      writeFields((dir_ / "fields" / numbered("frame_", f, ".vtu")).string(), sim);
    std::vector<Done> done;
    if (!s_.renderer) {
      done.push_back({physics, sinceStartUs(), sinceStartUs()});
      return done;
    }
    Job job{f, sim.snapshot(sc.look.displacementScale), sim.lastRecord()};
    if (!worker_.joinable()) {
      done.push_back(draw(job));
      return done;
    }
    std::unique_lock lock(mutex_);
    idle_.wait(lock, [this] { return !busy_; });
    takeFinished(done);
    job_ = std::move(job);
    busy_ = true;
    wake_.notify_one();
    return done;
  }

  // waits for the drawing thread to finish; returns the frame it finished (if any); throws
  // DrawFailure as add does
  std::vector<Done> drain() {
    std::vector<Done> done;
    if (!worker_.joinable()) return done;
    std::unique_lock lock(mutex_);
    idle_.wait(lock, [this] { return !busy_; });
    takeFinished(done);
    return done;
  }

  // the loop's start, against which doneUs is measured
  void startClock(Clock::time_point t0) { t0_ = t0; }
  bool pipelined() const { return worker_.joinable(); }

  ~FrameOutputs() { stopWorker(); }

  // closes the video (playable however many frames it has) and the label files, each even
  // when the other fails; the first error is rethrown
  void close() {
    stopWorker();
    std::exception_ptr first;
    try {
      if (labels_) labels_->close();
    } catch (...) {
      first = std::current_exception();
    }
    try {
      if (encoder_) {
        if (injectedFaultFrame("video_close") >= 0)
          throw Error("video: finishing '" + (dir_ / "video.mp4.partial").string() +
                      "' failed: No space left on device (injected: ESIM_FAULT)");  // its kind
        encoder_->close();
        encodeS_ = encoder_->encodeSeconds();
        codec_ = encoder_->codecName();
        encoder_.reset();
      }
    } catch (...) {
      if (!first) first = std::current_exception();
    }
    if (first) std::rethrow_exception(first);
  }

  double encodeSeconds() const { return encodeS_; }
  const std::string& codec() const { return codec_; }
  const nlohmann::json& frameHashes() const { return hashes_; }
  std::uint64_t allFramesHash() const { return allHash_.combined(); }
  bool hasLabels() const { return labels_ != nullptr; }
  std::uint64_t allMasksHash() const { return allMaskHash_.combined(); }

 private:
  struct Job {
    int frame;
    SurfaceSnapshot snapshot;
    FrameRecord record;  // the physics' stages, timed
  };

  double sinceStartUs() const {
    return std::chrono::duration<double, std::micro>(Clock::now() - t0_).count();
  }

  // renders the frame (timed into its record) and hands it to the encoder, hashes, labels
  // and PNGs (on the drawing thread when pipelined)
  Done draw(Job& job) {
    const Scenario& sc = s_.scenario;
    const int f = job.frame;
    if (f == drawFaultFrame_)  // (ESIM_FAULT=draw@N: a frame that cannot be drawn or written)
      throw Error("video: writing frame " + std::to_string(f) +
                  " failed: No space left on device (injected: ESIM_FAULT)");
    FrameRecord& rec = job.record;
    Done done;
    done.renderStartUs = sinceStartUs();
    const std::vector<std::uint8_t>* rgb = nullptr;
    const LabelFrame* labels = nullptr;
    {
      // the label pass draws the frame's buffers again: a part of rendering
      StageTimer timer(rec, Stage::Render);
      rgb = &s_.renderer->render(job.snapshot);
      if (labels_) labels = &s_.renderer->renderLabels();
    }
    const std::uint64_t h = hashFrame(*rgb);
    allHash_.add(h);
    hashes_.push_back({{"frame", f},
                       {"xxh3", hashToHex(h)},
                       {"dhash", hashToHex(perceptualHash(*rgb, sc.look.width, sc.look.height))}});
    if (labels) {
      const std::uint64_t mh = hashBytes(labels->classes.data(), labels->classes.size());
      allMaskHash_.add(mh);
      hashes_.back()["mask_xxh3"] = hashToHex(mh);
      hashes_.back()["depth_xxh3"] = hashToHex(depthHash(*labels));
      StageTimer timer(rec, Stage::Labels);
      labels_->add(f, job.snapshot, rec, *rgb, *labels);
    }
    if (sc.output.pngEvery > 0 && f % sc.output.pngEvery == 0)
      writePng((dir_ / "frames" / numbered("frame_", f, ".png")).string(), *rgb, sc.look.width,
               sc.look.height);
    if (encoder_) {
      StageTimer timer(rec, Stage::Encode);
      encoder_->push(*rgb);
    }
    done.record = rec;
    done.doneUs = sinceStartUs();
    return done;
  }

  // the drawing thread: one frame at a time, handed over by add
  void drawLoop() {
    for (;;) {
      std::unique_lock lock(mutex_);
      wake_.wait(lock, [this] { return job_.has_value() || quit_; });
      if (!job_) return;
      Job job = std::move(*job_);
      job_.reset();
      lock.unlock();
      std::optional<Done> done;
      std::exception_ptr error;
      try {
        done = draw(job);
      } catch (...) {
        error = std::current_exception();
      }
      lock.lock();
      if (error) {
        failure_ = DrawFailure{job.frame, error};  // the thread stops: see takeFinished
      } else {
        finished_ = std::move(done);
      }
      busy_ = false;
      idle_.notify_all();
      if (error) return;  // no frame is drawn after a failed one
    }
  }

  // (under mutex_) the finished frame into done, or the drawing thread's failure thrown
  void takeFinished(std::vector<Done>& done) {
    if (finished_) done.push_back(std::move(*finished_));
    finished_.reset();
    if (failure_) {
      const DrawFailure failure = *failure_;
      failure_.reset();
      throw failure;  // (the thread has stopped; the loop hands it nothing more)
    }
  }

  void stopWorker() {
    if (!worker_.joinable()) return;
    {
      std::lock_guard lock(mutex_);
      quit_ = true;
    }
    wake_.notify_one();
    worker_.join();
  }

  // fields of the phases the scene has, as VTU (README: fields for inspection)
  static void writeFields(const std::string& path, const Simulation& sim) {
    const TetMesh& m = sim.mesh();
    std::vector<VtuField> point, cell;
    std::vector<double> bc(m.numNodes(), 0.0);
    if (sim.hasElectric()) {
      const Eigen::VectorXd& u = sim.potentialV();
      point.push_back({"potential", 1, std::vector<double>(u.data(), u.data() + m.numNodes())});
      for (int v : sim.contactNodes()) bc[v] = 1;
      for (int v : sim.groundNodes()) bc[v] = 2;
      point.push_back({"bc", 1, bc});
      cell.push_back({"conductivity", 1, sim.conductivityS_m()});
      cell.push_back({"joule_power", 1, sim.joulePowerW_m3()});
    }
    if (const ThermalState* t = sim.thermalState()) {
      const Eigen::VectorXd& tc = t->temperatureC;
      point.push_back({"temperature", 1, std::vector<double>(tc.data(), tc.data() + m.numNodes())});
      if (!t->vaporFractionTet.empty()) cell.push_back({"vapor_fraction", 1, t->vaporFractionTet});
      if (!t->coagulationTet.empty()) cell.push_back({"coagulation", 1, t->coagulationTet});
    }
    if (const std::vector<double>* vm = sim.vonMisesPa()) {
      // the structural phase's displacement (ParaView: Warp By Vector) and load
      const Eigen::VectorXd& u = sim.state().displacementM;
      point.push_back({"displacement", 3, std::vector<double>(u.data(), u.data() + u.size())});
      cell.push_back({"expansion", 1, sim.state().eigenstrain});
      cell.push_back({"von_mises", 1, *vm});
    }
    std::vector<double> alive(m.numTets());
    for (int e = 0; e < m.numTets(); ++e) alive[e] = m.isAlive(e) ? 1.0 : 0.0;
    cell.push_back({"alive", 1, alive});
    writeVtu(path, m, point, cell);
  }

  // xxh3-64 of the depth values as little-endian 16-bit words
  std::uint64_t depthHash(const LabelFrame& labels) {
    depthBytes_.resize(labels.depth.size() * 2);
    for (size_t i = 0; i < labels.depth.size(); ++i) {
      depthBytes_[2 * i] = static_cast<std::uint8_t>(labels.depth[i] & 0xff);
      depthBytes_[2 * i + 1] = static_cast<std::uint8_t>(labels.depth[i] >> 8);
    }
    return hashBytes(depthBytes_.data(), depthBytes_.size());
  }

  const Setup& s_;
  fs::path dir_;
  std::unique_ptr<VideoEncoder> encoder_;
  std::unique_ptr<LabelWriter> labels_;
  nlohmann::json hashes_ = nlohmann::json::array();
  FrameHashSequence allHash_, allMaskHash_;
  std::vector<std::uint8_t> depthBytes_;  // scratch of depthHash
  double encodeS_ = 0;
  std::string codec_;
  Clock::time_point t0_ = Clock::now();
  int drawFaultFrame_ = injectedFaultFrame("draw");
  // the drawing thread and its one-frame hand-over
  std::thread worker_;
  std::atomic<int> idleThreads_{0};
  std::mutex mutex_;
  std::condition_variable wake_, idle_;
  std::optional<Job> job_;
  std::optional<Done> finished_;
  std::optional<DrawFailure> failure_;
  bool busy_ = false, quit_ = false;
};

// ---- progress ----

class Progress {
 public:
  Progress(int total, bool quiet) : total_(total), quiet_(quiet), tty_(isatty(2) != 0) {}
  void update(int done, double simTimeS) {
    if (quiet_) return;
    const double wall = secondsSince(start_);
    const double fps = wall > 0 ? done / wall : 0;
    const double eta = fps > 0 ? (total_ - done) / fps : 0;
    if (tty_) {
      const int width = 30, fill = total_ ? width * done / total_ : width;
      std::fprintf(stderr, "\r[%s%s] %d/%d frames  t=%.2f s  %.1f fps  ETA %.0f s ",
                   std::string(fill, '#').c_str(), std::string(width - fill, '-').c_str(), done,
                   total_, simTimeS, fps, eta);
      if (done == total_) std::fprintf(stderr, "\n");
    } else if (wall - lastLine_ >= 5.0 || done == total_) {
      lastLine_ = wall;
      std::fprintf(stderr, "esim: %d/%d frames, t=%.2f s, %.1f fps, ETA %.0f s\n", done, total_,
                   simTimeS, fps, eta);
    }
  }

 private:
  int total_;
  bool quiet_, tty_;
  Clock::time_point start_ = Clock::now();
  double lastLine_ = -1e9;
};

// ---- reports ----

// how the frame loop ended
struct LoopResult {
  std::vector<FrameRecord> records;
  std::vector<double> frameStartUs;
  std::vector<double> frameDoneUs;    // each frame's outputs done (from the loop's start)
  std::vector<double> renderStartUs;  // each frame's drawing started
  bool pipelined = false;             // drawn on a thread while the next frame was simulated
  int idleThreads = 0;                // --physics-first: the drawing's threads at SCHED_IDLE
  double loopS = 0;
  // CPU: the process's from the loop's start until the video is closed (the frames' own
  // encoding included; with output.encode: after, until the loop's end, the encoding then
  // following it), the loop's thread's over the loop, and that span's wall time [s]
  double cpuStartS = 0, loopThreadStartS = 0, cpuS = 0, loopThreadCpuS = 0, cpuWallS = 0;
  bool encodeAfter = false;  // the video encoded after the loop (output.encode: after)
  double peakPowerW = 0;
  bool interrupted = false;
  // as of the last complete frame (a frame that failed or was interrupted halfway leaves
  // the simulation's own totals halfway too)
  double energyJ = 0, maxTemperatureSeenC = 0, temperatureNowC = 0;
  std::string failure;  // the error that stopped the loop ("" = none)
  ErrorKind failureKind = ErrorKind::Run;
  double memoryRoomMinBytes = -1;  // the least memory left between frames (< 0: unknown)
  double peakResidentBytes = -1;   // the memory guard's largest peak read (it resets the
                                   // kernel's: see runPeakMb)
  struct CacheCut {
    int frame;
    double limitBytes, freedBytes;
  };
  std::vector<CacheCut> cacheCuts;  // the electric column cache cut for memory, after frames
  bool complete() const { return !interrupted && failure.empty(); }
};

// the run's peak resident memory [MB]: the memory guard sets the kernel's peak back after
// each frame (to see each frame's own), so it is the larger of what the guard read and what
// the kernel has counted since
double runPeakMb(const LoopResult& loop) {
  return std::max(peakRssMb(), loop.peakResidentBytes / 1048576.0);
}

std::vector<std::string> runWarnings(const Setup& s, double maxTemperatureSeenC) {
  const Simulation& sim = *s.sim;
  std::vector<std::string> warnings = sim.warnings();
  if (!s.viewWarning.empty()) warnings.push_back(s.viewWarning);
  if (maxTemperatureSeenC > kImplausibleTemperatureC) {
    // the remedies: a lower voltage, and what the scene does not do yet
    const SimulationConfig& c = sim.config();
    std::string remedies = "lower tool.voltage_v";
    std::vector<std::string> enable;
    if (!c.temperatureDependentConductivity)
      enable.push_back("effects.temperature_dependent_conductivity (drying cuts the current)");
    if (!(c.phases.structural && c.phases.rupture))
      enable.push_back("the structural and rupture phases (boiling tissue is removed)");
    for (size_t k = 0; k < enable.size(); ++k)
      remedies += (k == 0 ? ", or enable " : " or ") + enable[k];
    char w[200];
    std::snprintf(w, sizeof w,
                  "the tissue reached %.0f C: above ~%.0f C it chars and ablates, which the model "
                  "does not include; ",
                  maxTemperatureSeenC, kImplausibleTemperatureC);
    warnings.push_back(w + remedies);
  }
  return warnings;
}

// what the frames cost in CPU: whether the machine, not the scheduling, bounds the period
struct CpuUse {
  double msPerFrame = 0, loopThreadMsPerFrame = 0, busyCpus = 0, periodFloorMs = 0;
  int cpus = 1;
};

CpuUse cpuUse(const LoopResult& loop) {
  CpuUse c;
  c.cpus = usableCpus();
  const double frames = static_cast<double>(std::max<size_t>(1, loop.records.size()));
  c.msPerFrame = 1e3 * loop.cpuS / frames;
  c.loopThreadMsPerFrame = 1e3 * loop.loopThreadCpuS / frames;
  c.busyCpus = loop.cpuWallS > 0 ? loop.cpuS / loop.cpuWallS : 0.0;
  c.periodFloorMs = c.msPerFrame / c.cpus;
  return c;
}

nlohmann::json cpuJson(const LoopResult& loop) {
  const CpuUse c = cpuUse(loop);
  return {{"ms_per_frame", c.msPerFrame},
          {"loop_thread_ms_per_frame", c.loopThreadMsPerFrame},
          {"cpus", c.cpus},
          {"busy_cpus", c.busyCpus},
          {"period_floor_ms", c.periodFloorMs},
          {"note",
           std::string("CPU time of the whole process (every thread: the frame loop's, the "
                       "solvers' helpers, the renderer's, the encoder's) from the loop's start ") +
               (loop.encodeAfter ? "until its end (output.encode: after: the video is encoded "
                                   "after it, see offline.encode_s)"
                                 : "until the video is closed") +
               ", per frame run; busy_cpus: that time over the same span's wall time; "
               "period_floor_ms = ms_per_frame / cpus (the CPUs the process may run on): no "
               "scheduling gives a frame period below it"}};
}

// timing.json's block beyond the per-stage statistics
nlohmann::json timingExtra(const Setup& s, const FrameOutputs& out, const LoopResult& loop) {
  const Scenario& sc = s.scenario;
  const Simulation& sim = *s.sim;
  nlohmann::json extra;
  extra["scenario"] = sc.name;
  extra["scenario_hash"] = hashToHex(scenarioHash(sc));
  // the files the scenario names, by content: the scenario's hash covers their names only
  nlohmann::json inputs = nlohmann::json::object();
  const auto input = [&](const char* key, const std::string& path) {
    if (path.empty()) return;
    try {
      inputs[key] = {{"path", path}, {"xxh3", hashFile(path)}};
    } catch (const Error& e) {
      inputs[key] = {{"path", path}, {"xxh3", nullptr}, {"error", e.what()}};
    }
  };
  input("mesh.file.path", sc.mesh.source == MeshSource::File ? sc.mesh.file.resolvedPath : "");
  input("tool.path_file", sc.tool.pathFileResolved);
  extra["input_files"] = inputs;
  const PhaseSet& ph = sim.config().phases;
  nlohmann::json physics = nlohmann::json::array();
  for (const auto& [on, name] : {std::pair{ph.electric, "electric"},
                                 {ph.thermal, "thermal"},
                                 {ph.boiling, "boiling"},
                                 {ph.structural, "structural"},
                                 {ph.rupture, "rupture"}})
    if (on) physics.push_back(name);
  extra["physics"] = physics;
  extra["interrupted"] = loop.interrupted;
  extra["complete"] = loop.complete();
  if (!loop.failure.empty()) extra["failure"] = loop.failure;
  extra["mesh"] = {{"nodes", s.nodes}, {"tets", s.tets}, {"build_s", s.meshS}};
  extra["setup_s"] = s.setupS;
  extra["peak_rss_mb"] = runPeakMb(loop);
  extra["peak_rss_after_setup_mb"] = s.rssAfterSetupMb;
  if (loop.memoryRoomMinBytes >= 0) extra["memory_left_min_mb"] = loop.memoryRoomMinBytes / 1e6;
  extra["frame_loop_s"] = loop.loopS;
  // frames delivered: with the drawing on its own thread, the period is what a viewer sees,
  // the latency what a hand on the tool would (physics + render is each frame's own work)
  extra["draw_thread"] = loop.pipelined;
  extra["drawing_threads_idle"] = loop.idleThreads;  // --physics-first: moved to SCHED_IDLE
  const std::vector<double> periods = framePeriodsMs(loop.frameDoneUs);
  extra["frame_period"] = statsJson(seriesStats(periods));
  extra["frame_period"]["frames_over_budget"] = countOverBudget(periods);
  extra["frame_period"]["note"] =
      "wall time between frames whose outputs are done (video frame handed to the encoder)";
  extra["frame_latency"] =
      statsJson(seriesStats(frameLatenciesMs(loop.frameStartUs, loop.frameDoneUs)));
  extra["frame_latency"]["note"] = "from the start of a frame's physics to its outputs done";
  extra["offline"] = {
      {"encode_s", out.encodeSeconds()},
      {"codec", out.codec()},
      {"encode", sc.output.encode},
      {"note", sc.output.encode == "after"
                   ? "libav encoding after the frame loop (the frames kept raw until then)"
                   : "libav encoding on its own thread, not in the 30 Hz budget"}};
  extra["cpu"] = cpuJson(loop);
  extra["machine"] = machineInfo();
  extra["threads"] = {{"blas", sc.solvers.electricThreads},
                      {"encoder", sc.output.reproducible ? 1 : 0}};
  extra["electric_solver"] = sim.electricSolverName();
  extra["build"] = buildInfoJson(buildInfo());
  extra["electric_memory_mb"] = sim.electricMemoryBytes() / 1048576.0;
  extra["electric_cache_limit_mb"] = sc.solvers.electricCacheMemoryLimitMb;  // before any cut
  nlohmann::json cuts = nlohmann::json::array();
  for (const auto& c : loop.cacheCuts)
    cuts.push_back({{"after_frame", c.frame},
                    {"limit_mb", c.limitBytes / 1048576.0},
                    {"freed_mb", c.freedBytes / 1048576.0}});
  extra["electric_cache_cuts"] = cuts;
  extra["warnings"] = runWarnings(s, loop.maxTemperatureSeenC);
  if (sim.config().phases.structural)
    extra["structural"] = {
        {"removed_tets", sim.removedTets()},
        {"debris_tets", sim.debrisTets()},
        {"loose_pieces", sim.loosePieces()},
        {"loose_tets", sim.looseTets()},
        {"alive_tets", sim.mesh().numAlive()},
        {"rebuild_mode", rebuildModeName(sc.solvers.rebuildMode)},
        {"rebuild_lag_frames", sc.solvers.rebuildLagFrames},
        {"rebuilds", sim.rebuilds()},
        {"rebuilds_late", sim.rebuildsLate()},
        {"rebuild_build_ms_mean", sim.rebuilds() > 0 ? sim.rebuildBuildMs() / sim.rebuilds() : 0.0},
        {"rebuild_wait_ms_max", sim.maxRebuildWaitMs()},
        {"recomputed_frames", sim.recomputedFrames()},
        {"structural_refactorizations", sim.structuralRefactorizations()}};
  if (s.renderer)
    extra["renderer"] = {{"gl_renderer", s.renderer->glRenderer()},
                         {"gl_version", s.renderer->glVersion()},
                         {"platform", s.renderer->glPlatform()}};
  return extra;
}

nlohmann::json hashesJson(const Setup& s, const FrameOutputs& out, const nlohmann::json& extra) {
  const Scenario& sc = s.scenario;
  nlohmann::json hj;
  hj["frames"] = out.frameHashes();
  hj["all_frames_xxh3"] = hashToHex(out.allFramesHash());
  hj["hash_definition"] =
      "xxh3-64 (seed 0) of the raw RGB24 bytes, top row first; all_frames: xxh3-64 of the "
      "frame hashes as little-endian uint64; dhash: 64-bit difference hash (render/image_hash.h)";
  if (out.hasLabels()) {
    hj["all_masks_xxh3"] = hashToHex(out.allMasksHash());
    hj["labels_hash_definition"] =
        "mask_xxh3: xxh3-64 of the class bytes (labels/mask_NNNNN.png's pixels, top row "
        "first); depth_xxh3: of the depth values as little-endian uint16; all_masks: xxh3-64 "
        "of the mask hashes as little-endian uint64";
  }
  hj["width"] = sc.look.width;
  hj["height"] = sc.look.height;
  hj["renderer"] = extra["renderer"];
  hj["libraries"] = VideoEncoder::libraryVersions();
  // which esim made the frames (esim compare says when two runs' builds differ)
  hj["esim_build"] = buildInfoJson(buildInfo());
  hj["png_every"] = sc.output.pngEvery;
  hj["scenario_hash"] = extra["scenario_hash"];
  hj["input_files"] = extra["input_files"];
  hj["complete"] = extra["complete"];
  return hj;
}

void summaryStages(std::ostringstream& sum, const LoopResult& loop, const nlohmann::json& timing) {
  sum << "  stage          median ms     p95 ms   skipped\n";
  char line[200];
  for (int s = 0; s < kStageCount; ++s) {
    const StageStats st = stageStats(loop.records, static_cast<Stage>(s));
    if (st.ran + st.skipped == 0) continue;
    std::snprintf(line, sizeof line, "  %-14s %10.3f %10.3f %9d\n",
                  stageName(static_cast<Stage>(s)), st.p50Ms, st.p95Ms, st.skipped);
    sum << line;
  }
  std::vector<double> ms;
  for (const auto& r : loop.records) ms.push_back(interactiveMs(r));
  const StageStats inter = seriesStats(ms);
  std::snprintf(line, sizeof line,
                "  interactive    %10.3f %10.3f   (physics+render; %d of %d frames over 33.3 ms)\n",
                inter.p50Ms, inter.p95Ms, timing["frames_over_budget"].get<int>(),
                static_cast<int>(loop.records.size()));
  sum << line;
  // the period and latency as timing.json has them (timingExtra)
  const nlohmann::json& period = timing["frame_period"];
  const nlohmann::json& latency = timing["frame_latency"];
  std::snprintf(
      line, sizeof line,
      "  period         %10.3f %10.3f   (frames done, %d of %d over 33.3 ms; latency %.1f / "
      "%.1f ms%s)\n",
      period["p50_ms"].get<double>(), period["p95_ms"].get<double>(),
      period["frames_over_budget"].get<int>(), period["frames_ran"].get<int>(),
      latency["p50_ms"].get<double>(), latency["p95_ms"].get<double>(),
      loop.pipelined ? "; drawn on a thread while the next frame is simulated" : "");
  sum << line;
  if (loop.idleThreads > 0)
    sum << "  drawing       " << loop.idleThreads
        << " threads at SCHED_IDLE (--physics-first: drawn on CPU the physics does not want)\n";
}

void summaryStructural(std::ostringstream& sum, const Simulation& sim, const LoopResult& loop) {
  double peakVm = 0;
  for (const FrameRecord& r : loop.records) peakVm = std::max(peakVm, r.maxVonMisesPa);
  if (const std::vector<double>* vm = sim.vonMisesPa())  // a failed frame has no record
    for (double v : *vm) peakVm = std::max(peakVm, v);
  sum << "  structural    peak von Mises " << peakVm << " Pa; " << sim.removedTets()
      << " tets removed in " << sim.rebuilds() << " frames";
  if (sim.config().debrisVolumeM3 > 0)
    sum << ", " << sim.debrisTets() << " of them cut loose as debris";
  sum << " (" << sim.mesh().numAlive() << " of " << sim.mesh().numTets() << " alive";
  if (sim.loosePieces() > 0)
    sum << "; " << sim.loosePieces() << " loose pieces of " << sim.looseTets()
        << " tets left, stress-free and out of the stiffness";
  sum << ")\n";
  if (!sim.config().phases.rupture || sim.rebuilds() == 0) return;
  const SimulationConfig& c = sim.config();
  sum << "  rebuild       " << sim.rebuilds() << " rebuilds, "
      << (c.rebuildMode == RebuildMode::Background
              ? "background, swapped in " + std::to_string(c.rebuildLagFrames) +
                    " frames after the rupture"
              : std::string(rebuildModeName(c.rebuildMode)))
      << "; build " << sim.rebuildBuildMs() / sim.rebuilds() << " ms mean";
  if (c.rebuildMode == RebuildMode::Update)
    sum << "; the structural factor updated, refactorized " << sim.structuralRefactorizations()
        << (sim.structuralRefactorizations() == 1 ? " time" : " times");
  if (c.rebuildMode == RebuildMode::Background)
    sum << "; lag missed " << sim.rebuildsLate() << " times (longest wait "
        << sim.maxRebuildWaitMs() << " ms); " << sim.recomputedFrames() << " frames recomputed";
  sum << "\n";
}

std::string summaryText(const Setup& s, const FrameOutputs& out, const LoopResult& loop,
                        const nlohmann::json& timing, const fs::path& dir, bool plotted,
                        const std::string& video) {
  const Scenario& sc = s.scenario;
  const Simulation& sim = *s.sim;
  std::ostringstream sum;
  sum << std::fixed;
  sum.precision(2);
  sum << "esim run " << sc.name << (loop.interrupted ? "  (INTERRUPTED: partial)" : "")
      << (loop.failure.empty() ? "" : "  (FAILED: partial)") << "\n";
  if (!loop.failure.empty()) sum << "  error         " << loop.failure << "\n";
  sum << "  mesh        " << s.nodes << " nodes, " << s.tets << " tets (built in " << s.meshS
      << " s), setup " << s.setupS << " s\n";
  if (const std::string electric = sim.electricSolverName(); !electric.empty())
    sum << "  electric    " << electric
        << (sc.solvers.electricStrategy == ElectricStrategy::Auto
                ? " (solvers.electric.strategy auto)"
                : "")
        << "\n";
  sum << "  frames      " << loop.records.size() << " of " << s.frames << ", simulated "
      << sim.timeS() << " s at " << sc.time.fps << " fps, wall " << loop.loopS << " s\n";
  summaryStages(sum, loop, timing);
  sum << "  encode        " << out.encodeSeconds()
      << (loop.encodeAfter ? " s after the frame loop (output.encode: after)\n"
                           : " s offline (own thread)\n");
  const CpuUse cpu = cpuUse(loop);
  sum << "  cpu           " << cpu.msPerFrame << " ms a frame, all threads (the loop's own "
      << cpu.loopThreadMsPerFrame << " ms); " << cpu.busyCpus << " of " << cpu.cpus
      << " CPUs busy: no frame period below " << cpu.periodFloorMs << " ms here\n";
  sum << "  memory        peak " << runPeakMb(loop) << " MB resident (" << s.rssAfterSetupMb
      << " MB after setup)";
  if (loop.memoryRoomMinBytes >= 0)
    sum << ", at least " << std::lround(loop.memoryRoomMinBytes / 1e6) << " MB left between frames";
  if (!loop.cacheCuts.empty()) {
    const auto& last = loop.cacheCuts.back();
    sum << "; electric column cache cut to " << std::lround(last.limitBytes / 1048576.0)
        << " MB (memory short) after frame";
    for (size_t i = 0; i < loop.cacheCuts.size(); ++i)
      sum << (i ? ", " : " ") << loop.cacheCuts[i].frame;
  }
  sum << "\n";
  sum.precision(1);
  sum << "  temperature   max " << loop.maxTemperatureSeenC << " C (now " << loop.temperatureNowC
      << " C)\n";
  for (const std::string& w : runWarnings(s, loop.maxTemperatureSeenC))
    sum << "  WARNING       " << w << "\n";
  sum.precision(3);
  sum << "  energy        " << loop.energyJ << " J delivered, peak power " << loop.peakPowerW
      << " W\n";
  if (sim.config().subgrid.mode != SubgridMode::Off) {
    // the sub-grid contact model (sim/subgrid_contact.h): where it carried the contact
    int active = 0;
    double zoneMaxC = -INFINITY, vaporKg = 0, subJ = 0, pocketPa = 0;
    for (const FrameRecord& r : loop.records) {
      if (!r.subgridActive) continue;
      ++active;
      zoneMaxC = std::max(zoneMaxC, r.subgridZoneTemperatureC);
      pocketPa = std::max(pocketPa, r.subgridPocketStressPa);
      vaporKg += r.subgridVaporKg;
      subJ += r.subgridPowerW * sim.config().frameDtS;
    }
    sum << "  sub-grid      contact model (" << subgridModeName(sim.config().subgrid.mode)
        << ") on in " << active << " of " << loop.records.size() << " frames";
    if (active > 0)
      sum << "; zone peak " << zoneMaxC << " C, " << subJ << " J in its shell, " << vaporKg * 1e6
          << " mg of water vaporised"
          << (pocketPa > 0 ? ", vapour pockets' wall stress up to " : "")
          << (pocketPa > 0 ? std::to_string(static_cast<int>(pocketPa)) + " Pa" : "");
    sum << "\n";
  }
  if (sim.config().phases.structural) summaryStructural(sum, sim, loop);
  sum << "  outputs       " << dir.string() << "/ {" << (video.empty() ? "" : video + ", ")
      << "timing.csv, timing.json, trace.json, scenario.yaml" << (plotted ? ", timing.png" : "")
      << (s.renderer && sc.output.hashes ? ", hashes.json" : "")
      << (sc.output.pngEvery > 0 ? ", frames/" : "") << (s.fieldsEvery > 0 ? ", fields/" : "")
      << (s.labels.enabled ? ", labels/" : "") << "}\n";
  return sum.str();
}

// every report of the frames done (complete or not) into dir; returns the summary. With
// plots, timing.png too: a missing python3/matplotlib is a warning, never the run's failure. Each
// report is written whole or not at all (a disk that fills leaves no cut file)
std::string writeReports(const Setup& s, const FrameOutputs& out, const LoopResult& loop,
                         const fs::path& dir, const fs::path& finalDir, bool plots) {
  const nlohmann::json extra = timingExtra(s, out, loop);
  const nlohmann::json timing = timingJson(loop.records, extra);
  writeFileAtomic(dir / "timing.json", jsonText(timing, 2) + "\n");
  writeFileAtomic(dir / "timing.csv", timingCsv(loop.records, framePeriodsMs(loop.frameDoneUs)));
  writeFileAtomic(
      dir / "trace.json",
      jsonText(chromeTrace(loop.records, loop.frameStartUs,
                           loop.pipelined ? loop.renderStartUs : std::vector<double>{})) +
          "\n");
  writeFileAtomic(dir / "scenario.yaml", scenarioToYaml(s.scenario));
  if (s.renderer && s.scenario.output.hashes)
    writeFileAtomic(dir / "hashes.json", jsonText(hashesJson(s, out, extra), 2) + "\n");
  bool plotted = false;
  if (plots) {
    const PlotResult p = plotTiming(dir);
    plotted = p.status == PlotStatus::Written;
    if (!plotted)
      std::cerr << "esim: warning: no timing.png: " << printableMessage(p.message) << "\n";
  }
  // the video as it is (none after a failure that removed it, the fragmented file when only
  // its rewrite failed)
  std::error_code ec;
  const std::string video = !s.video                                    ? ""
                            : fs::exists(dir / "video.mp4", ec)         ? "video.mp4"
                            : fs::exists(dir / "video.mp4.partial", ec) ? "video.mp4.partial"
                                                                        : "";
  const std::string summary = summaryText(s, out, loop, timing, finalDir, plotted, video);
  writeFileAtomic(dir / "summary.txt", summary);
  return summary;
}

// ---- the frame loop ----

// the electric column cache is never cut below this for memory (a few hundred columns of a
// 30 000-node mesh; the contact set's own columns stay whatever the cap)
constexpr double kMinElectricCacheBytes = 64.0 * 1048576.0;

LoopResult frameLoop(Setup& s, FrameOutputs& out, TimingCsvStream& csv, bool quiet,
                     bool memoryGuard) {
  LoopResult loop;
  loop.maxTemperatureSeenC = loop.temperatureNowC = s.sim->temperatureC().maxCoeff();
  Progress progress(s.frames, quiet);
  const int badAllocFrame = injectedFaultFrame("bad_alloc");
  // ESIM_FAULT=alloc@N:MB: frame N takes MB megabytes more (touched) and holds them to the
  // end of the run, as a frame that needs a new large block (a rebuild's second model) does
  const int allocFrame = injectedFaultFrame("alloc");
  const std::size_t allocBytes = allocFrame < 0 ? 0 : injectedFaultMegabytes("alloc") * 1000000;
  std::vector<char> allocBlock;
  const int threadFaultFrame = injectedFaultFrame("thread");  // ESIM_FAULT=thread@N
  // ESIM_FAULT=kill@N: the process is killed (SIGKILL) once frame N is handed to its
  // outputs, as the kernel's out-of-memory killer or a scheduler's kill -9 would
  const int killFrame = injectedFaultFrame("kill");
  // memory left between frames: under the reserve, the electric column cache gives memory
  // back, else the run stops after a whole frame, reports written, rather than be killed in
  // the next one (memory_room.h; off with --no-memory-guard)
  MemoryGuard memory(memoryGuard ? memoryRootFromEnvironment() : fs::path());
  memory.check();  // the room at the start
  const auto t0 = Clock::now();
  loop.cpuStartS = processCpuSeconds();
  loop.loopThreadStartS = threadCpuSeconds();
  out.startClock(t0);
  loop.pipelined = out.pipelined();
  // the totals as of each frame handed to the outputs, kept until its outputs are done
  struct Totals {
    double energyJ, maxSeenC, nowC;
  };
  std::vector<Totals> totals;
  const auto finished = [&](std::vector<FrameOutputs::Done> done) {
    for (FrameOutputs::Done& d : done) {
      const Totals& t = totals[loop.records.size()];
      loop.peakPowerW = std::max(loop.peakPowerW, d.record.powerW);
      loop.energyJ = t.energyJ;
      loop.maxTemperatureSeenC = t.maxSeenC;
      loop.temperatureNowC = t.nowC;
      const double periodMs =
          (d.doneUs - (loop.frameDoneUs.empty() ? 0.0 : loop.frameDoneUs.back())) / 1000.0;
      loop.frameDoneUs.push_back(d.doneUs);
      loop.renderStartUs.push_back(d.renderStartUs);
      loop.records.push_back(std::move(d.record));
      csv.add(loop.records.back(), periodMs);
      progress.update(static_cast<int>(loop.records.size()), loop.records.back().timeS);
    }
  };
  // the address-space bound in force, for an out-of-memory message ("; a frame may map ...")
  const auto boundNote = [&memory]() -> std::string {
    const std::string& bound =
        memory.frameBound().empty() ? addressSpaceBound() : memory.frameBound();
    return bound.empty() ? "" : "; " + bound;
  };
  // a frame that failed (its outputs, or an earlier frame's drawing): the frames before it
  // are kept; false for a stop asked inside the frame (the frame dropped, no failure)
  const auto failed = [&](int f, std::exception_ptr error) {
    try {
      std::rethrow_exception(error);
    } catch (const FrameOutputs::DrawFailure& d) {  // the frame being drawn failed
      f = d.frame;
      error = d.error;
    } catch (...) {
    }
    try {
      std::rethrow_exception(error);
    } catch (const Interrupted&) {
    } catch (const std::bad_alloc&) {
      loop.failureKind = ErrorKind::Run;
      loop.failure = "frame " + std::to_string(f) +
                     ": out of memory (a smaller mesh, or another electric strategy: see "
                     "timing.json's electric_memory_mb)" +
                     boundNote();
    } catch (const fs::filesystem_error& e) {
      loop.failureKind = ErrorKind::Run;
      loop.failure = "frame " + std::to_string(f) + ": " + e.what();
    } catch (const std::system_error& e) {
      // a thread the frame needed could not be started (std::async, std::thread: its stack
      // refused under the address-space bound, or the user's thread limit, ulimit -u)
      const bool noThread = e.code() == std::errc::resource_unavailable_try_again ||
                            e.code() == std::errc::not_enough_memory;
      loop.failureKind = noThread ? ErrorKind::Run : ErrorKind::Internal;
      loop.failure = "frame " + std::to_string(f) + ": " +
                     (noThread ? "a thread could not be started (" + std::string(e.what()) +
                                     "): out of memory or of threads (ulimit -u)" + boundNote()
                               : "internal error: " + std::string(e.what()));
    } catch (const Error& e) {
      // the run cannot go on (a failed solve, all tissue gone, a tool reaching the return
      // electrode): the frames so far are kept
      loop.failureKind = e.kind();
      // (a stage's error may name its frame already: "rupture, frame N: ...",
      // "find_contacts, frame N: ...": a stage name has no space)
      const std::string what = e.what();
      const std::size_t at = what.find(", frame " + std::to_string(f) + ":");
      loop.failure = at != std::string::npos && what.find(' ') == at + 1
                         ? what
                         : "frame " + std::to_string(f) + ": " + what;
    } catch (const std::exception& e) {  // a defect: said as one, the frames so far kept
      loop.failureKind = ErrorKind::Internal;
      loop.failure = "frame " + std::to_string(f) + ": internal error: " + e.what();
    }
  };
  for (int f = 0; f < s.frames && !gStop; ++f) {
    loop.frameStartUs.push_back(
        std::chrono::duration<double, std::micro>(Clock::now() - t0).count());
    try {
      FrameRecord rec = s.sim->step();
      if (f == badAllocFrame) throw std::bad_alloc();
      if (f == allocFrame) std::vector<char>(allocBytes).swap(allocBlock);  // touched (zeroed)
      if (f == threadFaultFrame)  // what std::thread throws when no thread can be had
        throw std::system_error(std::make_error_code(std::errc::resource_unavailable_try_again),
                                "thread (injected: ESIM_FAULT)");
      totals.push_back(
          {s.sim->energyDeliveredJ(), s.sim->maxTemperatureSeenC(), rec.maxTemperatureC});
      finished(out.add(f, *s.sim, rec));
      if (f == killFrame) ::raise(SIGKILL);
    } catch (...) {
      failed(f, std::current_exception());
      break;
    }
    if (f + 1 == s.frames) break;  // the last frame: nothing left to keep room for
    if (std::string low = memory.check(); !low.empty()) {
      // first the electric column cache gives memory back (the fields stay the same, later
      // frames solve again the columns it no longer holds): its cap halved until columns
      // go, down to kMinElectricCacheBytes; the run stops only when none is left to give
      double cap = s.sim->config().electricSolver.cacheMemoryLimitBytes, freed = 0;
      while (freed <= 0 && cap > kMinElectricCacheBytes) {
        cap = std::max(kMinElectricCacheBytes, cap / 2);
        freed = s.sim->limitElectricCache(cap);
      }
      if (freed > 0) {
        ::malloc_trim(0);  // the columns' pages back to the system, not kept by malloc
        memory.released();
        loop.cacheCuts.push_back({f, cap, freed});
        continue;
      }
      loop.failureKind = ErrorKind::Run;
      loop.failure = "after frame " + std::to_string(f) + ": " + low;
      break;
    }
  }
  // the frame still being drawn
  try {
    finished(out.drain());
  } catch (...) {
    if (loop.failure.empty()) failed(-1, std::current_exception());
  }
  loop.frameStartUs.resize(loop.records.size());
  loop.memoryRoomMinBytes = memory.minRoomBytes();
  loop.peakResidentBytes = memory.peakResidentBytes();
  loop.interrupted = gStop.load();
  loop.loopS = secondsSince(t0);
  loop.idleThreads = out.idleThreads();
  loop.loopThreadCpuS = threadCpuSeconds() - loop.loopThreadStartS;
  loop.cpuS = processCpuSeconds() - loop.cpuStartS;  // until close adds to it
  loop.cpuWallS = loop.loopS;
  return loop;
}

}  // namespace

void requestStop() { gStop = true; }

int runScenario(const RunOptions& opt) {
  // SIGINT / SIGTERM from here on stop the run after the current frame (or before the
  // first), never in the middle of writing
  gStop = false;
  setInterruptFlag(&gStop);  // long work inside a frame checks it (core_error.h)
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);
  // ---- 1. scenario and output folder (checked before anything is built) ----
  Scenario scenario = loadScenario(opt.scenario, opt.sets);
  RunOutput output(opt.outDir.empty() ? defaultRunFolder(scenario.name) : fs::path(opt.outDir),
                   opt.overwrite);
  // ---- 2. mesh, physics, renderer ----
  Setup s = setUp(opt, std::move(scenario));
  // ---- 3. the partial folder and the video ----
  output.create();
  std::optional<FrameOutputs> out;
  try {
    out.emplace(s, output.partial(), opt.drawOnThread, opt.physicsFirst);
  } catch (...) {
    output.discard();
    throw;
  }
  // ---- 4. frames ----
  // (timing.csv's rows as the frames are done: what a killed run leaves of its reports)
  TimingCsvStream csv((output.partial() / "timing.csv.partial").string());
  LoopResult loop = frameLoop(s, *out, csv, opt.quiet, !opt.noMemoryGuard);
  // ---- 5. close the video, write the reports, rename when complete ----
  // (a video that cannot be finished, a disk full at the end, fails the run: exit 1, its
  // reports in DIR.partial; it escaped as a bad input, exit 2, without them)
  const auto closeFailed = [&loop](const std::string& what, ErrorKind kind) {
    if (!loop.failure.empty()) return;  // the first failure is the run's
    loop.failure = "closing the outputs: " + what;
    loop.failureKind = kind == ErrorKind::Internal ? kind : ErrorKind::Run;
  };
  const auto closeStart = Clock::now();
  try {
    out->close();
  } catch (const Error& e) {
    closeFailed(e.what(), e.kind());
  } catch (const fs::filesystem_error& e) {
    closeFailed(e.what(), ErrorKind::Run);
  } catch (const std::bad_alloc&) {
    closeFailed("out of memory", ErrorKind::Run);
  }
  loop.encodeAfter = s.video && s.scenario.output.encode == "after";
  if (!loop.encodeAfter) {  // (after: the loop's own, taken at its end)
    loop.cpuS = processCpuSeconds() - loop.cpuStartS;
    loop.cpuWallS = loop.loopS + secondsSince(closeStart);
  }
  const fs::path where = loop.complete() ? output.final() : output.partial();
  std::string summary;
  try {
    summary = writeReports(s, *out, loop, output.partial(), where, opt.plots);
    csv.remove();  // timing.csv has every row
  } catch (const Error& e) {
    // a disk that filled: the run's own failure first (often the same cause), then the reports'
    // (it said only "timing.csv: write failed"); the run stays in DIR.partial
    if (!loop.failure.empty())
      std::cerr << "esim: error: " << printableMessage(loop.failure) << "\n";
    std::cerr << "esim: error: the run's reports could not be written: "
              << printableMessage(e.what()) << "\n";
    return e.kind() == ErrorKind::Internal ? kExitInternal : kExitFailure;
  }
  if (loop.complete()) {
    try {
      output.commit();
    } catch (const Error& e) {  // a file put into DIR since the checks: the run stays partial
      std::cout << printableMessage(summary);
      std::cerr << "esim: error: " << printableMessage(e.what()) << "\n";
      return kExitFailure;
    }
  }
  std::cout << printableMessage(summary);
  if (!loop.failure.empty()) std::cerr << "esim: error: " << printableMessage(loop.failure) << "\n";
  if (loop.complete()) return kExitOk;
  // a run error or an interruption: 1 (the frames are kept); an internal check: 4
  return !loop.failure.empty() && loop.failureKind == ErrorKind::Internal ? kExitInternal
                                                                          : kExitFailure;
}

}  // namespace esim::app
