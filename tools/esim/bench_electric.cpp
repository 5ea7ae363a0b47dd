// bench_electric.cpp - `esim bench electric`: the four electric strategies side by
// side on slab meshes with a blade sweeping the top surface (a benchmark: a table,
// never pass/fail).
//
// 1. Parse options (--sizes, --frames, --csv, --strategies, --threads, ...).
// 2. Per size: build the paper's slab (100 x 100 x 10 mm) with ~N nodes, K with
//    sigma = 0.144 S/m, the 40 mm return disc on the bottom, and the contact set of
//    every frame: a vertical blade (3 mm wide along the cut, 0.5 mm thick) whose
//    tip edge is 0.5 mm below the top face, cutting from x = -40 mm to +40 mm by
//    one grid spacing h per frame, in serpentine passes 3h apart; contact distance
//    h, so every size sees a few nodes change per frame.
// 3. Reference: a fresh CHOLMOD factorization of the reduced system on a sample of
//    frames.
// 4. Per strategy: pre-processing (setMatrix) time, then per-frame solve times
//    (median, p95), memory, max relative error vs the reference; dense-inverse is
//    skipped with a note where its n^2 memory exceeds the limit. Capacitance is
//    given the surface as contact candidates (patches of 16 solved together). The extra row
//    capacitance+prefetch prefetches the columns of every node the scripted path
//    will touch during the pre-processing (a scenario's tool path is known).
// 5. Print the table with each strategy's ratio to dense-inverse and to refactor;
//    write the CSV.
// 6. Fig. 9(a) of the paper: refactor vs dense-inverse with 1 and 2 BLAS threads at
//    506 and 1013 nodes, a new contact set every frame; percentages next to the
//    paper's.
// 7. With --update (issue #11): a cut removes --update-tets tets next to the blade's
//    path; updateMatrix vs a fresh setMatrix, then the first solve with a contact set
//    whose columns were cached and one with columns to solve (capacitance: simplicial
//    LDL' after an update vs supernodal LL' after setMatrix).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "sim/core_error.h"
#include "sim/electric_solver.h"
#include "sim/electrode.h"
#include "sim/fem_p1.h"
#include "sim/mesh_slab.h"
#include "sim/message_text.h"
#include "tools/app/bench_common.h"
#include "tools/esim/command.h"

namespace esim::cli {
using namespace ::esim::app;
namespace {

using Clock = std::chrono::steady_clock;

struct BenchElectricOptions {
  std::string sizes = "506,1013,5000,20000,50000";
  int frames = 120;
  std::string csv;
  std::string strategies = "refactor,dense-inverse,capacitance,pcg";
  int threads = 1;
  double pcgTolerance = 1e-8;
  std::string pcgPreconditioner = "two-level";
  double denseLimitGb = 2.0;
  int errorFrames = 24;
  bool fig9 = true;
  bool pathPrefetch = true;
  int fig9Frames = 60;
  bool update = false;      // the updateMatrix table
  bool onlyUpdate = false;  // only that table
  std::string updateSizes = "1013,8000,20000,50000";
  std::string updateTets = "5";
  std::string updateStrategies =
      "capacitance,capacitance-downdate,downdate,refactor,pcg,dense-inverse";
  int updateReps = 1;
  double localMarginM = 0.006;  // local's region radius [m]
  int localRefreshFrames = 3;   // local's far-field refresh period
};

double seconds(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

// a solver to bench: auto is a choice between two of them, not one
ElectricStrategy parseBenchStrategy(const std::string& item, const char* option) {
  const ElectricStrategy s = parseElectricStrategy(item);
  if (s == ElectricStrategy::Auto)
    throw Error(std::string("bench electric: ") + option +
                ": 'auto' is not a solver of its own: it takes dense-inverse up to " +
                messageNumber(kAutoDenseMaxFreeNodes) +
                " free nodes and capacitance above; list those to compare them");
  return s;
}

std::vector<ElectricStrategy> parseStrategies(const std::string& text) {
  std::vector<ElectricStrategy> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) out.push_back(parseBenchStrategy(item, "--strategies"));
  return out;
}

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const double pos = q * (v.size() - 1);
  const size_t lo = static_cast<size_t>(std::floor(pos));
  const size_t hi = std::min(lo + 1, v.size() - 1);
  return v[lo] + (pos - lo) * (v[hi] - v[lo]);
}

// ---- the test problem ----

struct Scene {
  TetMesh mesh;
  SparseMatrix K;
  std::vector<int> grounded;
  std::vector<int> surface;                // boundary nodes (contact candidates)
  std::vector<std::vector<int>> contacts;  // per frame
  double spacingM = 0;
};

Scene buildScene(int targetNodes) {
  Scene s;
  SlabSpec spec;
  spec.targetNodes = targetNodes;
  s.mesh = makeSlab(spec);
  const auto px = slabNodesPerAxis(spec);
  s.spacingM = spec.sizeM.x() / (px[0] - 1);
  s.K =
      assembleStiffness(s.mesh, tetGeometry(s.mesh), std::vector<double>(s.mesh.numTets(), 0.144));
  s.surface = boundaryNodes(s.mesh, boundaryFaces(s.mesh));
  s.grounded = returnElectrodeNodes(s.mesh, s.surface, ReturnElectrode{});
  return s;
}

// the blade's contact without the return electrode's nodes: on a coarse slab the contact
// distance (one grid spacing) reaches through the slab to its bottom
std::vector<int> bladeContact(const Scene& s, const ContactFinder& finder, const ToolPose& pose) {
  std::vector<int> c = finder.find(ElectrodeShape{}, pose, s.spacingM), out;
  std::set_difference(c.begin(), c.end(), s.grounded.begin(), s.grounded.end(),
                      std::back_inserter(out));
  return out;
}

// blade cutting left to right, one grid spacing per frame (so a few contact nodes
// change every frame), in parallel passes 3 spacings apart (serpentine) when a pass
// reaches x = +/-40 mm
void sweepContacts(Scene& s, int frames) {
  const auto surface = boundaryNodes(s.mesh, boundaryFaces(s.mesh));
  const ContactFinder finder(s.mesh, surface);
  // the blade: 3 mm wide, 0.5 mm thick, 20 mm long (ElectrodeShape's defaults)
  const double top = s.mesh.nodes[s.mesh.nodeSets.at("top").front()].z();
  const double h = s.spacingM;
  const int perPass = std::max(2, static_cast<int>(0.08 / h) + 1);
  s.contacts.clear();
  for (int f = 0; f < frames; ++f) {
    const int pass = f / perPass, k = f % perPass;
    const double along = -0.04 + k * h;
    const double x = pass % 2 == 0 ? along : -along;
    const double y = std::fmod(0.3 * h + pass * 3 * h + 0.04, 0.08) - 0.04;
    const ToolPose pose{Vec3(x, y, top - 0.0005), Eigen::Quaterniond::Identity()};
    s.contacts.push_back(bladeContact(s, finder, pose));
  }
}

// the tool jumps to a new spot every frame (pseudo-random, fixed seed)
void jumpingContacts(Scene& s, int frames) {
  const auto surface = boundaryNodes(s.mesh, boundaryFaces(s.mesh));
  const ContactFinder finder(s.mesh, surface);
  const double top = s.mesh.nodes[s.mesh.nodeSets.at("top").front()].z();
  unsigned state = 12345;
  const auto next = [&] {
    state = state * 1103515245u + 12345u;
    return ((state >> 8) & 0xffff) / 65535.0;
  };
  s.contacts.clear();
  for (int f = 0; f < frames; ++f) {
    const ToolPose pose{Vec3(-0.04 + 0.08 * next(), -0.04 + 0.08 * next(), top - 0.0005),
                        Eigen::Quaterniond::Identity()};
    s.contacts.push_back(bladeContact(s, finder, pose));
  }
}

// fresh direct solve: CHOLMOD on K_ff with the contact rows set to the identity
Eigen::VectorXd referencePotential(const Scene& s, const std::vector<int>& contact, double v) {
  auto solver = makeElectricSolver({.strategy = ElectricStrategy::Refactor});
  solver->setMatrix(s.K, s.grounded);
  Eigen::VectorXd u;
  solver->solve(contact, v, u);
  return u;
}

struct Row {
  std::string strategy;
  int nodes = 0;
  std::optional<double> precomputeS, medianMs, p95Ms, meanMs, memoryMb, maxRelError;
  std::string note;
};

// runs one strategy over the scene's frames
// the solver options the bench's options give a strategy (both tables)
ElectricSolverOptions solverOptions(const BenchElectricOptions& opt, ElectricStrategy strategy) {
  ElectricSolverOptions so;
  so.strategy = strategy;
  so.threads = opt.threads;
  so.pcgTolerance = opt.pcgTolerance;
  so.pcgPreconditioner = opt.pcgPreconditioner == "jacobi" ? PcgPreconditioner::Jacobi
                         : opt.pcgPreconditioner == "ic"   ? PcgPreconditioner::IncompleteCholesky
                                                           : PcgPreconditioner::TwoLevel;
  so.denseMemoryLimitBytes = opt.denseLimitGb * 1e9;
  so.localMarginM = opt.localMarginM;
  so.localRefreshFrames = opt.localRefreshFrames;
  return so;
}

// (pathPrefetch: the contact nodes of the whole scripted path are prefetched as part
// of the pre-processing, capacitance only)
Row runStrategy(const Scene& s, ElectricStrategy strategy, const BenchElectricOptions& opt,
                const std::vector<int>& sampleFrames, const std::vector<Eigen::VectorXd>& refs,
                std::vector<double>* frameMs = nullptr, bool pathPrefetch = false) {
  Row row;
  row.strategy = electricStrategyName(strategy);
  if (pathPrefetch) row.strategy += "+prefetch";
  row.nodes = s.mesh.numNodes();
  auto solver = makeElectricSolver(solverOptions(opt, strategy));
  const auto t0 = Clock::now();
  try {
    solver->setNodePositions(s.mesh.nodes);
    solver->setContactCandidates(s.surface);
    solver->setMatrix(s.K, s.grounded);
    if (pathPrefetch) {
      std::vector<int> path;
      for (const auto& c : s.contacts) path.insert(path.end(), c.begin(), c.end());
      std::sort(path.begin(), path.end());
      path.erase(std::unique(path.begin(), path.end()), path.end());
      solver->prefetch(path);
    }
  } catch (const Error& e) {
    row.note = std::string("skipped: ") + e.what();
    return row;
  }
  row.precomputeS = seconds(t0, Clock::now());
  Eigen::VectorXd u = Eigen::VectorXd::Zero(s.mesh.numNodes());
  std::vector<double> times;
  double maxErr = 0;
  long newColumns = 0, refactors = 0, iterations = 0, regionNodes = 0;
  size_t sample = 0;
  for (size_t f = 0; f < s.contacts.size(); ++f) {
    const auto a = Clock::now();
    const ElectricSolveStats st = solver->solve(s.contacts[f], 72.0, u);
    times.push_back(1e3 * seconds(a, Clock::now()));
    newColumns += st.newColumns;
    refactors += st.refactored;
    iterations += st.iterations;
    regionNodes += st.regionNodes;
    if (sample < sampleFrames.size() && sampleFrames[sample] == static_cast<int>(f)) {
      const Eigen::VectorXd& ref = refs[sample++];
      maxErr = std::max(maxErr, (u - ref).cwiseAbs().maxCoeff() / ref.cwiseAbs().maxCoeff());
    }
  }
  if (frameMs) *frameMs = times;
  row.medianMs = percentile(times, 0.5);
  row.p95Ms = percentile(times, 0.95);
  double sum = 0;
  for (double t : times) sum += t;
  row.meanMs = sum / std::max<size_t>(1, times.size());
  row.memoryMb = solver->memoryBytes() / 1e6;
  row.maxRelError = maxErr;
  char note[160];
  const double nf = static_cast<double>(s.contacts.size());
  if (strategy == ElectricStrategy::Refactor)
    std::snprintf(note, sizeof note, "%ld refactorizations", refactors);
  else if (strategy == ElectricStrategy::Capacitance)
    std::snprintf(note, sizeof note, "%.2f new columns/frame%s", newColumns / nf,
                  pathPrefetch ? " (path prefetched at setup)" : "");
  else if (strategy == ElectricStrategy::Pcg)
    std::snprintf(note, sizeof note, "%.1f iterations/frame (%s, tol %.0e)", iterations / nf,
                  opt.pcgPreconditioner.c_str(), opt.pcgTolerance);
  else if (strategy == ElectricStrategy::Local)
    std::snprintf(note, sizeof note,
                  "%.0f region nodes/frame (margin %g mm, far field refreshed every %d), %.1f "
                  "iterations/frame",
                  regionNodes / nf, 1e3 * opt.localMarginM, opt.localRefreshFrames,
                  iterations / nf);
  else
    note[0] = 0;
  row.note = note;
  return row;
}

std::string fmt(const std::optional<double>& v, const char* f) {
  if (!v) return "";
  char buf[64];
  std::snprintf(buf, sizeof buf, f, *v);
  return buf;
}

std::string csvQuote(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string out = "\"";
  for (char c : s) out += (c == '"') ? std::string("\"\"") : std::string(1, c);
  return out + "\"";
}

// ---- Fig. 9(a) ----

void runFig9(const BenchElectricOptions& opt) {
  std::printf(
      "\nFig. 9(a) of the paper: conventional (refactor) vs proposed (dense-inverse), "
      "1 and 2 BLAS threads,\na new contact set every frame (the tool jumps), %d frames, "
      "mean ms per frame (best of 3 runs):\n",
      opt.fig9Frames);
  std::printf("%7s %14s %14s %14s %14s %9s %9s %9s\n", "nodes", "refactor 1t", "refactor 2t",
              "dense 1t", "dense 2t", "threads", "method", "both");
  for (int n : {506, 1013}) {
    Scene s = buildScene(n);
    jumpingContacts(s, opt.fig9Frames);
    double mean[2][2];  // [method][threads-1]
    for (int m = 0; m < 2; ++m)
      for (int t = 1; t <= 2; ++t) {
        BenchElectricOptions o = opt;
        o.threads = t;
        // best of 3 runs: the machine is shared, the minimum is the least disturbed
        mean[m][t - 1] = 1e300;
        for (int rep = 0; rep < 3; ++rep) {
          std::vector<double> ms;
          runStrategy(s, m == 0 ? ElectricStrategy::Refactor : ElectricStrategy::DenseInverse, o,
                      {}, {}, &ms);
          double sum = 0;
          for (double x : ms) sum += x;
          mean[m][t - 1] = std::min(mean[m][t - 1], sum / std::max<size_t>(1, ms.size()));
        }
      }
    const double base = mean[0][0];
    std::printf("%7d %14.4f %14.4f %14.4f %14.4f %8.1f%% %8.1f%% %8.1f%%\n", s.mesh.numNodes(),
                mean[0][0], mean[0][1], mean[1][0], mean[1][1], 100 * (mean[0][1] - base) / base,
                100 * (mean[1][0] - base) / base, 100 * (mean[1][1] - base) / base);
  }
  std::printf(
      "%7s %14s %14s %14s %14s %8.1f%% %8.1f%% %8.1f%%   (paper, 1013 nodes, MKL, "
      "3 threads)\n",
      "paper", "", "", "", "", -26.6, -45.1, -59.7);
  std::printf(
      "threads: refactor 2t vs 1t; method: dense 1t vs refactor 1t; both: dense 2t vs "
      "refactor 1t.\n");
  setBlasThreads(1);
}

// ---- updateMatrix after a cut ----

struct UpdateTiming {
  double updateMs = 0, setMs = 0;  // updateMatrix; fresh setMatrix (+candidates)
  double updateAllMs = 0;          // updateMatrix told nothing of the change (every column read)
  bool sameBits = true;            // ... its potential the same, bit for bit
  double cachedAfterMs = 0, cachedFreshMs = 0;  // first solve, contact columns cached before
  double newAfterMs = 0, newFreshMs = 0;        // solve with columns to compute
  int newAfter = 0, newFresh = 0;               // columns computed in those solves
  double maxRelError = 0;                       // updated vs fresh potential
  ElectricUpdateStats stats;
};

// one cut on a scene for one strategy: the solver has run `warmFrames` frames of the
// sweep (capacitance: their columns are cached), then `tets` tets nearest the top of the
// path at x = 0 are removed; the update told the removed tets' nodes (as the frame loop
// tells it), and a second solver's update told nothing (blindFirst: that one first)
UpdateTiming timeUpdate(const Scene& s, ElectricStrategy strategy, const BenchElectricOptions& opt,
                        int tets, bool downdate, bool blindFirst) {
  ElectricSolverOptions so = solverOptions(opt, strategy);
  if (downdate) so.capacitanceUpdate = CapacitanceUpdate::Downdate;
  const int warmFrames = std::min<int>(40, s.contacts.size() - 1);
  // the cut: alive tets whose centroid is nearest the top of the first pass at x = 0
  const double top = s.mesh.nodes[s.mesh.nodeSets.at("top").front()].z();
  const Vec3 at(0.0, s.contacts.empty() ? 0.0 : 0.3 * s.spacingM - 0.0, top);
  std::vector<std::pair<double, int>> byDistance;
  for (int e = 0; e < s.mesh.numTets(); ++e) {
    Vec3 c = Vec3::Zero();
    for (int v : s.mesh.tets[e]) c += 0.25 * s.mesh.nodes[v];
    byDistance.emplace_back((c - at).squaredNorm(), e);
  }
  std::partial_sort(byDistance.begin(), byDistance.begin() + tets, byDistance.end());
  TetMesh cut = s.mesh;
  std::vector<int> removed;
  for (int k = 0; k < tets; ++k) removed.push_back(byDistance[k].second);
  for (int e : removed) cut.alive[e] = 0;
  const std::vector<int> changed = nodesOfTets(cut, removed);  // the columns of K that change
  // K after the cut as the frame loop makes it: the removed tets' entries summed again in
  // place (the pattern kept, explicit zeros: bitwise a fresh assembly's values)
  SparseMatrix K = s.K;
  removeFromStiffness(K, cut, tetGeometry(cut), std::vector<double>(cut.numTets(), 0.144),
                      nodeTets(s.mesh), removed);
  const std::vector<int> surface = boundaryNodes(cut, boundaryFaces(cut));
  const std::vector<int> grounded = returnElectrodeNodes(cut, surface, ReturnElectrode{});
  // a contact set cached before the cut, one far from the warm frames (columns to solve)
  const std::vector<int>& cachedContact = s.contacts[warmFrames - 1];
  const std::vector<int>& newContact = s.contacts.back();
  UpdateTiming t;
  // a solver warmed by the frames, then updated (told the changed nodes, or not)
  Eigen::VectorXd warm;  // pcg: every solve after the cut starts from here
  const auto warmed = [&](std::unique_ptr<ElectricSolver>& solver, Eigen::VectorXd& u) {
    solver = makeElectricSolver(so);
    solver->setNodePositions(s.mesh.nodes);  // (local's region; a cut moves no node)
    solver->setContactCandidates(s.surface);
    solver->setMatrix(s.K, s.grounded);
    u = Eigen::VectorXd::Zero(s.mesh.numNodes());
    for (int f = 0; f < warmFrames; ++f) solver->solve(s.contacts[f], 72.0, u);
    warm = u;
  };
  std::unique_ptr<ElectricSolver> solver, blind;
  Eigen::VectorXd u, ub, uf;
  Clock::time_point a;
  const auto updateBlind = [&] {
    warmed(blind, ub);
    a = Clock::now();
    blind->updateMatrix(K, grounded);
    blind->setContactCandidates(surface);
    t.updateAllMs = 1e3 * seconds(a, Clock::now());
    blind->solve(cachedContact, 72.0, ub);
  };
  if (blindFirst) updateBlind();
  warmed(solver, u);
  a = Clock::now();
  t.stats = solver->updateMatrix(K, grounded, &changed);
  solver->setContactCandidates(surface);
  t.updateMs = 1e3 * seconds(a, Clock::now());
  if (!blindFirst) {
    const Eigen::VectorXd kept = u;
    updateBlind();
    u = kept;
    warm = kept;  // (pcg's start below)
  }
  a = Clock::now();
  solver->solve(cachedContact, 72.0, u);
  t.cachedAfterMs = 1e3 * seconds(a, Clock::now());
  t.sameBits = (u.array() == ub.array()).all();
  // fresh
  auto fresh = makeElectricSolver(so);
  fresh->setNodePositions(cut.nodes);
  a = Clock::now();
  fresh->setContactCandidates(surface);
  fresh->setMatrix(K, grounded);
  t.setMs = 1e3 * seconds(a, Clock::now());
  uf = warm;
  a = Clock::now();
  fresh->solve(cachedContact, 72.0, uf);
  t.cachedFreshMs = 1e3 * seconds(a, Clock::now());
  t.maxRelError = (u - uf).cwiseAbs().maxCoeff() / uf.cwiseAbs().maxCoeff();
  a = Clock::now();
  t.newAfter = solver->solve(newContact, 72.0, u).newColumns;
  t.newAfterMs = 1e3 * seconds(a, Clock::now());
  a = Clock::now();
  t.newFresh = fresh->solve(newContact, 72.0, uf).newColumns;
  t.newFreshMs = 1e3 * seconds(a, Clock::now());
  t.maxRelError =
      std::max(t.maxRelError, (u - uf).cwiseAbs().maxCoeff() / uf.cwiseAbs().maxCoeff());
  return t;
}

// --update-strategies: strategies, and "capacitance-downdate" (capacitance with
// CapacitanceUpdate::Downdate)
std::vector<std::pair<ElectricStrategy, bool>> parseUpdateStrategies(const std::string& text) {
  std::vector<std::pair<ElectricStrategy, bool>> strategies;
  for (const std::string& item : app::splitList(text)) {
    if (item == "capacitance-downdate")
      strategies.emplace_back(ElectricStrategy::Capacitance, true);
    else
      strategies.emplace_back(parseBenchStrategy(item, "--update-strategies"), false);
  }
  return strategies;
}

// the solvers' options (both tables), checked before any table runs, by the bench's names
// (an invalid one made every row "skipped" with the scenario key's message)
void checkSolverOptions(const BenchElectricOptions& opt) {
  ESIM_VERIFY(opt.threads >= 1,
              "bench electric: --threads must be >= 1, got " + std::to_string(opt.threads));
  ESIM_VERIFY(
      std::isfinite(opt.pcgTolerance) && opt.pcgTolerance > 0 && opt.pcgTolerance < 1,
      "bench electric: --pcg-tolerance must be in (0, 1), got " + messageNumber(opt.pcgTolerance));
  ESIM_VERIFY(
      std::isfinite(opt.denseLimitGb) && opt.denseLimitGb > 0,
      "bench electric: --dense-limit-gb must be > 0, got " + messageNumber(opt.denseLimitGb));
  ESIM_VERIFY(
      std::isfinite(opt.localMarginM) && opt.localMarginM > 0,
      "bench electric: --local-margin must be > 0 m, got " + messageNumber(opt.localMarginM));
  ESIM_VERIFY(opt.localRefreshFrames >= 1, "bench electric: --local-refresh must be >= 1, got " +
                                               std::to_string(opt.localRefreshFrames));
}

// the update table's options, checked before any table runs
struct UpdatePlan {
  std::vector<int> sizes, tetCounts;
  std::vector<std::pair<ElectricStrategy, bool>> strategies;
};

UpdatePlan checkUpdateOptions(const BenchElectricOptions& opt) {
  UpdatePlan plan;
  plan.sizes = app::parseNodeCounts(opt.updateSizes, "bench electric", "--update-sizes");
  plan.strategies = parseUpdateStrategies(opt.updateStrategies);
  ESIM_VERIFY(!plan.strategies.empty(),
              "--update-strategies is empty (expected e.g. downdate,pcg,capacitance)");
  plan.tetCounts = app::parseIntegerList(opt.updateTets, "--update-tets", 1, 100000000, "5,95");
  ESIM_VERIFY(opt.updateReps >= 1,
              "--update-reps must be >= 1, got " + std::to_string(opt.updateReps));
  // each cut must leave tets: the slab of each size (built alone: its mesh is cheap) against
  // the largest cut
  const int most = *std::max_element(plan.tetCounts.begin(), plan.tetCounts.end());
  for (int target : plan.sizes) {
    SlabSpec spec;
    spec.targetNodes = target;
    const TetMesh mesh = makeSlab(spec);
    ESIM_VERIFY(most < mesh.numTets(), "--update-tets: " + std::to_string(most) +
                                           " tets is not less than the " +
                                           std::to_string(mesh.numNodes()) + "-node slab's " +
                                           std::to_string(mesh.numTets()) + " (--update-sizes " +
                                           std::to_string(target) + ")");
  }
  return plan;
}

void runUpdate(const BenchElectricOptions& opt, const UpdatePlan& plan) {
  const std::vector<int>& sizes = plan.sizes;
  const std::vector<std::pair<ElectricStrategy, bool>>& strategies = plan.strategies;
  const std::vector<int>& tetCounts = plan.tetCounts;
  std::printf(
      "\nupdateMatrix after a cut (issue #11): tets removed at the top of the blade path, %d "
      "warm frames solved before;\nupdate = updateMatrix told the removed tets' nodes + "
      "setContactCandidates(new surface),\nupd_all = the same told nothing (every column read), "
      "set = fresh setContactCandidates + setMatrix;\ncached = first solve of a contact set "
      "solved before the cut; new = a contact set never solved (n columns computed);\n"
      "best of %d run(s), ms\n",
      40, opt.updateReps);
  std::printf("%-20s %7s %5s %10s %10s %10s %8s %10s %10s %10s %10s %9s  %s\n", "strategy", "nodes",
              "tets", "update_ms", "upd_all_ms", "set_ms", "set/upd", "cached_up", "cached_fr",
              "new_up", "new_fr", "rel_err", "what was done");
  for (int target : sizes) {
    Scene s = buildScene(target);
    sweepContacts(s, std::max(opt.frames, 60));
    for (int tets : tetCounts) {
      for (const auto& [st, downdate] : strategies) {
        const std::string name =
            std::string(electricStrategyName(st)) + (downdate ? "-downdate" : "");
        UpdateTiming best;
        bool have = false;
        std::string skipped;
        for (int rep = 0; rep < std::max(1, opt.updateReps); ++rep) {
          UpdateTiming t;
          try {
            t = timeUpdate(s, st, opt, tets, downdate, rep % 2 == 1);
          } catch (const Error& e) {
            skipped = e.what();
            break;
          }
          const double all = have ? std::min(best.updateAllMs, t.updateAllMs) : t.updateAllMs;
          const bool same = (!have || best.sameBits) && t.sameBits;
          if (!have || t.updateMs < best.updateMs) best = t;
          best.updateAllMs = all;
          best.sameBits = same;
          have = true;
        }
        if (!have) {
          std::printf("%-20s %7d %5d  skipped: %s\n", name.c_str(), s.mesh.numNodes(), tets,
                      skipped.c_str());
          continue;
        }
        const ElectricUpdateStats& u = best.stats;
        char what[256];
        if (u.fellBack)
          std::snprintf(what, sizeof what, "fell back: %s", u.fallbackReason.c_str());
        else if (st == ElectricStrategy::Local)  // not exact: its region against a full solve
          std::snprintf(what, sizeof what,
                        "rows %d, dropped %d, the held far field kept; rel_err: its region "
                        "solve against a fresh solver's first (full) solve",
                        u.changedNodes, u.droppedNodes);
        else
          std::snprintf(
              what, sizeof what, "rows %d, dropped %d, rank %d, columns corrected %d dropped %d",
              u.changedNodes, u.droppedNodes, u.rank, u.columnsCorrected, u.columnsDropped);
        char newUp[32], newFr[32];
        std::snprintf(newUp, sizeof newUp, "%.2f(%d)", best.newAfterMs, best.newAfter);
        std::snprintf(newFr, sizeof newFr, "%.2f(%d)", best.newFreshMs, best.newFresh);
        std::printf(
            "%-20s %7d %5d %10.3f %10.3f %10.2f %8.1f %10.3f %10.3f %10s %10s %9.1e  %s%s\n",
            name.c_str(), s.mesh.numNodes(), tets, best.updateMs, best.updateAllMs, best.setMs,
            best.setMs / std::max(best.updateMs, 1e-6), best.cachedAfterMs, best.cachedFreshMs,
            newUp, newFr, best.maxRelError, what,
            best.sameBits ? "" : "; NOT the same bits as upd_all");
        std::fflush(stdout);
      }
    }
  }
  setBlasThreads(1);
}

int benchElectric(const BenchElectricOptions& opt) {
  checkSolverOptions(opt);
  if (opt.onlyUpdate) {
    runUpdate(opt, checkUpdateOptions(opt));
    return kExitOk;
  }
  // 1. options
  const std::vector<int> sizes = app::parseNodeCounts(opt.sizes, "bench electric");
  const std::vector<ElectricStrategy> strategies = parseStrategies(opt.strategies);
  UpdatePlan updatePlan;
  if (opt.update) updatePlan = checkUpdateOptions(opt);  // checked before the first run
  ESIM_VERIFY(opt.frames >= 1, "bench electric: --frames must be >= 1");
  app::CsvOutput csv(opt.csv,
                     "strategy,nodes,precompute_s,median_ms,p95_ms,memory_mb,max_rel_error,note");
  std::vector<Row> rows;
  std::printf(
      "esim bench electric: blade cutting x = -40..40 mm by one grid spacing per frame "
      "(serpentine passes) on the 100x100x10 mm slab, %d frames, %d BLAS thread(s), pcg tol %.0e\n",
      opt.frames, opt.threads, opt.pcgTolerance);
  std::printf("(timings on a shared machine: other jobs may be running)\n\n");
  std::printf("%-21s %7s %11s %10s %10s %10s %10s %10s %9s %9s  %s\n", "strategy", "nodes",
              "precomp_s", "median_ms", "p95_ms", "mean_ms", "memory_mb", "max_err", "/dense",
              "/refac", "note");
  for (int target : sizes) {
    // 2. scene
    Scene s = buildScene(target);
    sweepContacts(s, opt.frames);
    double meanContacts = 0, changes = 0;
    for (size_t f = 0; f < s.contacts.size(); ++f) {
      meanContacts += s.contacts[f].size();
      if (f > 0 && s.contacts[f] != s.contacts[f - 1]) ++changes;
    }
    meanContacts /= s.contacts.size();
    // 3. reference on a sample of frames
    std::vector<int> sampleFrames;
    const int ns = std::max(1, std::min(opt.errorFrames, opt.frames));
    for (int k = 0; k < ns; ++k) {
      const int f =
          static_cast<int>(std::lround(double(k) * (opt.frames - 1) / std::max(1, ns - 1)));
      if (sampleFrames.empty() || sampleFrames.back() != f) sampleFrames.push_back(f);
    }
    std::vector<Eigen::VectorXd> refs;
    for (int f : sampleFrames) refs.push_back(referencePotential(s, s.contacts[f], 72.0));
    // 4. strategies
    std::vector<Row> sizeRows;
    for (ElectricStrategy st : strategies) {
      sizeRows.push_back(runStrategy(s, st, opt, sampleFrames, refs));
      if (st == ElectricStrategy::Capacitance && opt.pathPrefetch)
        sizeRows.push_back(runStrategy(s, st, opt, sampleFrames, refs, nullptr, true));
    }
    // 5. table with ratios
    std::optional<double> dense, refac;
    for (const Row& r : sizeRows) {
      if (r.strategy == "dense-inverse") dense = r.medianMs;
      if (r.strategy == "refactor") refac = r.medianMs;
    }
    std::printf(
        "-- %d nodes, %.1f contact nodes/frame on average, contact set changed in %.0f "
        "of %d frames\n",
        s.mesh.numNodes(), meanContacts, changes, opt.frames);
    for (const Row& r : sizeRows) {
      std::optional<double> toDense, toRefac;
      if (r.medianMs && dense && *dense > 0) toDense = *r.medianMs / *dense;
      if (r.medianMs && refac && *refac > 0) toRefac = *r.medianMs / *refac;
      std::printf("%-21s %7d %11s %10s %10s %10s %10s %10s %9s %9s  %s\n", r.strategy.c_str(),
                  r.nodes, fmt(r.precomputeS, "%.4f").c_str(), fmt(r.medianMs, "%.4f").c_str(),
                  fmt(r.p95Ms, "%.4f").c_str(), fmt(r.meanMs, "%.4f").c_str(),
                  fmt(r.memoryMb, "%.1f").c_str(), fmt(r.maxRelError, "%.1e").c_str(),
                  fmt(toDense, "%.3g").c_str(), fmt(toRefac, "%.3g").c_str(), r.note.c_str());
      std::fflush(stdout);
    }
    rows.insert(rows.end(), sizeRows.begin(), sizeRows.end());
  }
  // CSV
  if (csv) {
    std::ostringstream& out = csv.out();
    for (const Row& r : rows)
      out << r.strategy << ',' << r.nodes << ',' << fmt(r.precomputeS, "%.6f") << ','
          << fmt(r.medianMs, "%.6f") << ',' << fmt(r.p95Ms, "%.6f") << ','
          << fmt(r.memoryMb, "%.3f") << ',' << fmt(r.maxRelError, "%.3e") << ',' << csvQuote(r.note)
          << '\n';
    csv.commit();
    std::printf("\nwrote %s\n", printablePath(opt.csv).c_str());
  }
  // 6. the paper's Fig. 9(a)
  if (opt.fig9) runFig9(opt);
  // 7. updateMatrix after a cut
  if (opt.update) runUpdate(opt, updatePlan);
  return kExitOk;
}

const Registrar registrar(
    {"bench", "electric"},
    "Electric solver strategies side by side on slab meshes (refactor, dense-inverse, "
    "capacitance, pcg)",
    [](CLI::App& app) -> Runner {
      auto opt = std::make_shared<BenchElectricOptions>();
      // the blade sweep's options, which --only-update would silently ignore
      std::vector<const CLI::Option*> sweep;
      sweep.push_back(app.add_option("--sizes", opt->sizes, "comma-separated slab node counts")
                          ->capture_default_str());
      app.add_option("--frames", opt->frames,
                     "frames of the blade sweep (the update table warms up on at least 60)")
          ->capture_default_str();
      sweep.push_back(app.add_option("--csv", opt->csv,
                                     "write one row per strategy and size to this CSV file"));
      sweep.push_back(
          app.add_option("--strategies", opt->strategies, "comma-separated strategies to run")
              ->capture_default_str());
      // the solvers' options: both tables
      app.add_option("--threads", opt->threads, "BLAS threads")->capture_default_str();
      app.add_option("--pcg-tolerance", opt->pcgTolerance, "pcg relative residual")
          ->capture_default_str();
      app.add_option("--pcg-preconditioner", opt->pcgPreconditioner, "two-level, jacobi or ic")
          ->check(CLI::IsMember({"two-level", "jacobi", "ic"}))
          ->capture_default_str();
      app.add_option("--dense-limit-gb", opt->denseLimitGb, "dense-inverse memory limit [GB]")
          ->capture_default_str();
      sweep.push_back(app.add_option("--error-frames", opt->errorFrames,
                                     "frames compared against a fresh direct solve")
                          ->capture_default_str());
      sweep.push_back(
          app.add_option("--fig9-frames", opt->fig9Frames, "frames of the Fig. 9(a) runs")
              ->capture_default_str());
      app.add_option("--local-margin", opt->localMarginM,
                     "local: the region's radius around the contacts [m]")
          ->capture_default_str();
      app.add_option("--local-refresh", opt->localRefreshFrames,
                     "local: frames between the far field's full solves")
          ->capture_default_str();
      sweep.push_back(
          app.add_flag("!--no-fig9", opt->fig9, "skip the paper's Fig. 9(a) comparison"));
      sweep.push_back(
          app.add_flag("!--no-prefetch", opt->pathPrefetch,
                       "skip the capacitance+prefetch row (scripted path prefetched at setup)"));
      app.add_flag("--update", opt->update, "also the updateMatrix-after-a-cut table");
      app.add_flag("--only-update", opt->onlyUpdate, "only the updateMatrix-after-a-cut table");
      std::vector<const CLI::Option*> update;  // the update table's own
      update.push_back(
          app.add_option("--update-sizes", opt->updateSizes, "node counts of the update table")
              ->capture_default_str());
      update.push_back(
          app.add_option("--update-tets", opt->updateTets, "comma-separated tets removed per cut")
              ->capture_default_str());
      update.push_back(app.add_option("--update-strategies", opt->updateStrategies,
                                      "strategies of the update table")
                           ->capture_default_str());
      update.push_back(app.add_option("--update-reps", opt->updateReps, "runs per row (best taken)")
                           ->capture_default_str());
      return [opt, sweep, update] {
        // (they were read only with the table: without it, `--update-sizes qqq` ran the whole
        // sweep table and exited 0)
        if (!opt->update && !opt->onlyUpdate)
          refuseGiven(update, "bench electric",
                      "is an option of the update table; add --update (both tables) or "
                      "--only-update");
        if (opt->onlyUpdate)
          refuseGiven(sweep, "bench electric",
                      "is an option of the blade-sweep table, which --only-update skips (the "
                      "update table's: --update-sizes, --update-tets, --update-strategies, "
                      "--update-reps, and the solvers' --threads, --pcg-tolerance, "
                      "--pcg-preconditioner, --dense-limit-gb, --local-margin, --local-refresh)");
        return benchElectric(*opt);
      };
    });

}  // namespace
}  // namespace esim::cli
