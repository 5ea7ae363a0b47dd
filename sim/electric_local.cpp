// electric_local.cpp - the potential solved around the tool only, its far field held from
// an earlier full solve refreshed on a thread (strategy `local`; issue #11, "the structural
// solve at scale" for the electric phase). Not exact: it trades a measured error for time
// (README, "The potential solved around the tool, built").
//
// Method (the "held" model of tools/electric_local_study, measured there first):
//   - a full solve (pcg, the same options) gives the potential u_h on every node, held
//     (scaled by the tool voltage's ratio when it changes: the potential is linear in it);
//   - each frame the region R is the set of free nodes, not in contact, within
//     localMarginM of a contact node of this frame or of the held solve, reached from
//     those nodes through such nodes (a breadth-first walk over the nonzeros of K): u_h
//     is wrong around both (the tool has moved since), so both are solved; every other
//     node keeps s u_h (contacts: the tool voltage, the return electrode and floating
//     nodes: 0 V);
//   - R is solved twice for its boundary (conjugate gradients, Jacobi preconditioned,
//     warm-started from u_h, to pcgTolerance): u_1 with the tool's voltage and u_h outside,
//     u_H with 0 V at the tool and u_h outside; u_V = u_1 - u_H. The scale s minimizes the
//     energy of u_V + s u_H (s = -u_V'K u_H / u_H'K u_H: one product with K). The result is
//     the energy minimum over the functions equal to a multiple of u_h outside R, so its
//     Joule power is at least the true one and falls as R grows, s = 1 when u_h is exact,
//     and a region covering the body gives the full solve's answer. Without s (s = 1) a
//     contact set that shrinks (a blade's flickers on a graded mesh: 3 nodes, 1, 3) kept
//     the held field's larger current: on slab_cut the power's error p95 1.4e-1 against
//     6.4e-3 with s (README). At 50k nodes, ~5900 region nodes: ~90 iterations a solve,
//     6-20 ms with the refresh running beside it; incomplete Cholesky in BFS order took
//     28-31 iterations but 8.7-18 ms, in AMD order 14-57 ms (ESIM_LOCAL_DEBUG timings of
//     one solve a frame, since removed);
//   - every localRefreshFrames solves a full solve with that frame's contacts starts on a
//     thread (at nice +10) and is adopted localRefreshFrames solves later: the far field is
//     R to 2R - 1 frames (solves with contact) old. The adoption points depend only on the
//     count of solves, so a run is deterministic whatever the thread's timing;
//   - the first solve after the solver is made (or when the held field's size no longer
//     matches), and a frame whose contacts have jumped (a new contact farther than half the
//     margin from, and not next to, every contact of the held solve: see movedAway), is a
//     full solve in the frame by a second pcg solver, exact, held from then on; a refresh
//     in flight then is not waited for (it is dropped when due). Waiting for it made the
//     liver's solve_potential p95 105 ms against pcg's 61 (README).
// setMatrix / updateMatrix: the region side takes the new K at once; the full solver gets
// it when its next refresh starts (a refresh in flight is never waited for here). A cut told
// its changed nodes costs the change: the node classes edited in place (FreeBase, as pcg's),
// the changed columns copied into the region's K and, at the next refresh's start, into the
// refresh thread's copy (both when K keeps its pattern, as the frame loop's in-place edit
// does; else, or untold, the whole of K). At 50k nodes 0.11-0.16 ms against 3.5-4.6 ms for
// the whole copy and the classes' search (esim bench electric --only-update); in the cut 0.36
// against 4.0-4.2 ms a removal (README). The two inner pcg solvers take a cut as an update in
// place (pcg's updateMatrix, told the union of the changed nodes since they last took a
// matrix; told nothing when one of those cuts came without its list), not as a new matrix:
// on the refresh thread at 50k nodes 0.4-6.5 ms against 14-15 ms for pcg's setMatrix.
// Thread safety: as every ElectricSolver; the refresh thread touches only the inner solver
// and its own buffers, joined before they are read.
#include <Eigen/IterativeLinearSolvers>
#include <algorithm>
#include <future>
#include <iterator>
#include <memory>
#include <string>
#include <utility>

#include "sim/core_error.h"
#include "sim/electric_solver.h"

namespace esim::electric_detail {
namespace {

// a jump: a contact farther than this many margins from the held solve's contacts
constexpr double kJumpMargins = 0.5;

// to's columns `changed` (sorted) given from's values, in place, when every one of them has
// the same place and rows in both (then, as their other columns are the same by
// updateMatrix's contract, both have one pattern): O(the columns' entries). False: nothing
// copied (not told, another pattern, or not compressed), the caller copies all of it
bool copyColumns(const SparseMatrix& from, const std::vector<int>* changed, SparseMatrix& to) {
  if (!changed || !from.isCompressed() || !to.isCompressed() || from.rows() != to.rows() ||
      from.cols() != to.cols() || from.nonZeros() != to.nonZeros())
    return false;
  const int* fo = from.outerIndexPtr();
  const int* tout = to.outerIndexPtr();
  for (int j : *changed) {
    if (j < 0 || j >= from.cols() || fo[j] != tout[j] || fo[j + 1] != tout[j + 1] ||
        !std::equal(from.innerIndexPtr() + fo[j], from.innerIndexPtr() + fo[j + 1],
                    to.innerIndexPtr() + tout[j]))
      return false;
  }
  for (int j : *changed)
    std::copy(from.valuePtr() + fo[j], from.valuePtr() + fo[j + 1], to.valuePtr() + tout[j]);
  return true;
}

class LocalSolver final : public ElectricSolver {
 public:
  explicit LocalSolver(const ElectricSolverOptions& options) : options_(options) {
    ElectricSolverOptions inner = options;
    inner.strategy = ElectricStrategy::Pcg;
    full_ = makePcgSolver(inner);
    now_ = makePcgSolver(inner);
    cg_.setTolerance(options_.pcgTolerance);
    cg_.setMaxIterations(options_.pcgMaxIterations);
  }
  ~LocalSolver() override {
    if (refresh_.valid()) refresh_.wait();  // the thread uses full_ and refreshed_
  }
  LocalSolver(const LocalSolver&) = delete;
  LocalSolver& operator=(const LocalSolver&) = delete;

  void setNodePositions(const std::vector<Vec3>& positionsM) override { positions_ = positionsM; }

  void setMatrix(const SparseMatrix& K, const std::vector<int>& grounded) override {
    const ResetOnThrow guard(free_.current);
    free_.set(K, grounded);
    K_ = K;
    K_.makeCompressed();
    grounded_ = grounded;
    pending_ = true;  // the full solver takes it at its next start
    nowPending_ = true;
    fullChange_ = nowChange_ = InnerChange{};  // a new matrix for both
  }

  // the region side takes the change: its node classes in place (FreeBase, as pcg's) and
  // the changed columns of K (all of K when not told them, or when their pattern moved);
  // the held far field stays; the inner solvers get the change when they next take the
  // matrix
  ElectricUpdateStats updateMatrix(const SparseMatrix& K, const std::vector<int>& grounded,
                                   const std::vector<int>* changedNodes) override {
    ESIM_CHECK(free_.current.n > 0);  // setMatrix before updateMatrix
    const ResetOnThrow guard(free_.current);
    BaseChange change;
    ElectricUpdateStats stats =
        updateFreeBase(free_, K, grounded, changedNodes, change, [&] { free_.set(K, grounded); });
    if (!copyColumns(K, changedNodes, K_)) {
      K_ = K;
      K_.makeCompressed();
    }
    grounded_ = grounded;
    fullChange_.add(changedNodes);
    nowChange_.add(changedNodes);
    pending_ = nowPending_ = true;
    return stats;
  }

  ElectricSolveStats solve(const std::vector<int>& contact, double voltageV,
                           Eigen::VectorXd& potential) override {
    ESIM_CHECK(free_.current.n > 0);  // setMatrix before solve
    ESIM_VERIFY(static_cast<int>(positions_.size()) == free_.current.n,
                "electric solver local: node positions (" + std::to_string(positions_.size()) +
                    ") do not match the matrix (" + std::to_string(free_.current.n) + " nodes)");
    ElectricSolveStats stats;
    if (free_.contactsOrZero(contact, potential).empty()) return stats;
    ++solves_;
    const bool due = solves_ >= nextRefresh_;
    if (due && refresh_.valid()) {  // adopt the refresh started R solves ago
      refresh_.get();               // rethrows the refresh's error here
      if (!dropRefresh_) {
        std::swap(held_, refreshed_);
        heldVoltageV_ = refreshedVoltageV_;
        heldContact_ = refreshedContact_;
      }
      dropRefresh_ = false;
    }
    // nothing held yet, or the tool has jumped away from the held solve's contacts: a full
    // solve in the frame by a second solver (a refresh in flight is not waited for: it is of
    // the old place, dropped when it is due), held from now on
    if (held_.size() != free_.current.n || movedAway(contact)) {
      if (refresh_.valid()) dropRefresh_ = true;
      fullSolve(contact, voltageV, potential, stats);
      held_ = potential;
      heldVoltageV_ = voltageV;
      heldContact_ = contact;
      solves_ = 0;
      nextRefresh_ = options_.localRefreshFrames;
      if (options_.localCheck) stats.powerError = 0;  // the full solve itself
      return stats;
    }
    if (due) {  // start the next refresh, adopted R solves from now
      startRefresh(contact, voltageV);
      nextRefresh_ = solves_ + options_.localRefreshFrames;
    }
    regionSolve(contact, voltageV, potential, stats);
    if (options_.localCheck) checkPower(contact, voltageV, potential, stats);
    return stats;
  }

  double memoryBytes() const override {
    return full_->memoryBytes() + now_->memoryBytes() +
           12.0 *
               static_cast<double>(K_.nonZeros() + refreshK_.nonZeros() + free_.matrix.nonZeros()) +
           8.0 * 6 * static_cast<double>(free_.current.n);
  }
  const char* name() const override { return "local"; }

 private:
  // a full solve in the frame into `potential` (now_, the matrix given first if it changed)
  void fullSolve(const std::vector<int>& contact, double voltageV, Eigen::VectorXd& potential,
                 ElectricSolveStats& stats) {
    if (nowPending_) {
      nowChange_.give(*now_, K_, grounded_);
      nowPending_ = false;
    }
    stats = now_->solve(contact, voltageV, potential);
    stats.regionNodes = free_.current.numFree();
  }

  // a contact node of this frame farther than kJumpMargins * localMarginM from every contact
  // node of the held solve and not next to one (an edge of K: a coarse mesh's contacts move
  // node by node): the tool has jumped (a new path, a pass's end), and the held far
  // field is that of the old place. A blade moving continuously adds contacts at its front
  // edge, as far from the held ones as it has travelled since (slab_cut: 1/3 mm a frame, so
  // 1.7 mm at the held field's oldest with the defaults: never). Contacts that were held
  // cost a binary search; only new ones are compared with the held set.
  bool movedAway(const std::vector<int>& contact) const {
    const double reach2 =
        kJumpMargins * kJumpMargins * options_.localMarginM * options_.localMarginM;
    for (int c : contact) {
      if (free_.current.freeIndex[c] < 0 ||
          std::binary_search(heldContact_.begin(), heldContact_.end(), c))
        continue;
      bool near = false;
      for (SparseMatrix::InnerIterator it(K_, c); it && !near; ++it)  // one edge away
        near = std::binary_search(heldContact_.begin(), heldContact_.end(),
                                  static_cast<int>(it.row()));
      for (size_t k = 0; k < heldContact_.size() && !near; ++k)
        near = (positions_[c] - positions_[heldContact_[k]]).squaredNorm() <= reach2;
      if (!near) return true;
    }
    return false;
  }

  void startRefresh(const std::vector<int>& contact, double voltageV) {
    if (pending_) {  // the thread gets its own copy: K_ may change while it runs (the thread
                     // is joined here: the copy takes the columns changed since the last)
      const bool told = fullChange_.hasMatrix && fullChange_.told;
      if (!told || !copyColumns(K_, &fullChange_.changedNodes, refreshK_)) refreshK_ = K_;
      refreshGrounded_ = grounded_;
      refreshChange_ = std::move(fullChange_);
      fullChange_ = InnerChange::taken();
    }
    const bool newMatrix = pending_;
    pending_ = false;
    refreshed_ = held_;  // the warm start
    refreshedVoltageV_ = voltageV;
    refreshedContact_ = contact;
    if (heldVoltageV_ != 0 && voltageV != heldVoltageV_) refreshed_ *= voltageV / heldVoltageV_;
    refresh_ = std::async(std::launch::async, [this, contact, voltageV, newMatrix] {
      deprioritizeThisThread();  // needed R frames from now: the frame loop goes first
      if (newMatrix) refreshChange_.give(*full_, refreshK_, refreshGrounded_);
      full_->solve(contact, voltageV, refreshed_);
    });
  }

  // the region around the contacts solved with the held field outside
  void regionSolve(const std::vector<int>& contact, double voltageV, Eigen::VectorXd& potential,
                   ElectricSolveStats& stats) {
    const CurrentClasses& classes = free_.current;
    const int n = classes.n;
    const double scale = heldVoltageV_ != 0 ? voltageV / heldVoltageV_ : 1.0;
    potential.resize(n);
    for (int i = 0; i < n; ++i) potential[i] = classes.freeIndex[i] >= 0 ? scale * held_[i] : 0.0;
    mark_.assign(n, -1);  // -2 contact, -3 seen and outside, >= 0 index in region
    region_.clear();
    std::vector<int>& queue = queue_;
    queue.clear();
    centres_.clear();  // the nodes the margin is measured from
    for (int c : contact)
      if (classes.freeIndex[c] >= 0) {
        potential[c] = voltageV;
        mark_[c] = -2;
        queue.push_back(c);
        centres_.push_back(c);
      }
    // the held solve's contacts: u_h is the tool's potential there, no longer touched
    for (int c : heldContact_)
      if (c < n && classes.freeIndex[c] >= 0 && mark_[c] == -1) {
        mark_[c] = static_cast<int>(region_.size());
        region_.push_back(c);
        queue.push_back(c);
        centres_.push_back(c);
      }

    // ---- the region: a walk from those nodes through free nodes within the margin ----
    const double margin2 = options_.localMarginM * options_.localMarginM;
    for (size_t head = 0; head < queue.size(); ++head) {
      for (SparseMatrix::InnerIterator it(K_, queue[head]); it; ++it) {
        const int v = static_cast<int>(it.row());
        if (mark_[v] != -1) continue;
        bool inside = classes.freeIndex[v] >= 0;
        if (inside) {
          inside = false;
          for (int c : centres_)
            if ((positions_[v] - positions_[c]).squaredNorm() < margin2) {
              inside = true;
              break;
            }
        }
        if (!inside) {
          mark_[v] = -3;
          continue;
        }
        mark_[v] = static_cast<int>(region_.size());
        region_.push_back(v);
        queue.push_back(v);
      }
    }
    const int m = static_cast<int>(region_.size());
    stats.regionNodes = m;
    if (m == 0) return;

    // ---- K_RR, and the two right-hand sides: from the contacts (b_V) and the held field
    // outside (b_H); K symmetric: its columns are its rows ----
    entries_.clear();
    b1_.setZero(m);  // b_V + b_H
    bH_.setZero(m);
    guess_.resize(m);
    for (int q = 0; q < m; ++q) {
      const int v = region_[q];
      guess_[q] = potential[v];
      for (SparseMatrix::InnerIterator it(K_, v); it; ++it) {
        const int j = static_cast<int>(it.row());
        if (mark_[j] >= 0) {
          entries_.emplace_back(mark_[j], q, it.value());
        } else if (mark_[j] == -2) {
          b1_[q] -= it.value() * voltageV;
        } else {
          b1_[q] -= it.value() * potential[j];
          bH_[q] -= it.value() * potential[j];
        }
      }
    }
    A_.resize(m, m);
    A_.setFromTriplets(entries_.begin(), entries_.end());
    cg_.compute(A_);
    // u_1: the region with the tool's voltage and the held field (warm: the held values);
    // u_H: with the contacts at 0 V instead; u_V = u_1 - u_H
    regionCg(b1_, x1_, stats);
    regionCg(bH_, xH_, stats);
    const Eigen::VectorXd& x1 = x1_;
    const Eigen::VectorXd& xH = xH_;

    // ---- the far field's scale s: the energy minimum over u_V + s u_H (Galerkin) ----
    // uH_ (full size): xH in the region, the held field outside, 0 at the contacts and at
    // the fixed nodes; then E_HH = u_H' K u_H and E_VH = u_V' K u_H (u_V is nonzero on the
    // region and the contacts only)
    uH_ = potential;
    for (int c : centres_)
      if (mark_[c] == -2) uH_[c] = 0.0;
    for (int q = 0; q < m; ++q) uH_[region_[q]] = xH[q];
    kuH_.noalias() = K_ * uH_;
    const double eHH = uH_.dot(kuH_);
    double eVH = 0;
    for (int q = 0; q < m; ++q) eVH += (x1[q] - xH[q]) * kuH_[region_[q]];
    for (int c : centres_)
      if (mark_[c] == -2) eVH += voltageV * kuH_[c];
    const double sFar = eHH > 0 ? -eVH / eHH : 1.0;
    stats.farFieldScale = sFar;
    for (int i = 0; i < n; ++i)
      if (mark_[i] != -2) potential[i] = sFar * uH_[i];
    for (int q = 0; q < m; ++q) potential[region_[q]] = x1[q] - xH[q] + sFar * xH[q];
  }

  // localCheck: the power's relative excess over a full solve of this frame
  void checkPower(const std::vector<int>& contact, double voltageV,
                  const Eigen::VectorXd& potential, ElectricSolveStats& stats) {
    if (!check_) {
      ElectricSolverOptions o = options_;
      o.strategy = ElectricStrategy::Pcg;
      o.pcgTolerance = 1e-10;
      check_ = makePcgSolver(o);
    }
    check_->setMatrix(K_, grounded_);
    checkU_ = potential;  // the warm start
    check_->solve(contact, voltageV, checkU_);
    const double exact = checkU_.dot(K_ * checkU_);
    stats.powerError = exact > 0 ? potential.dot(K_ * potential) / exact - 1.0 : 0.0;
  }

  // CG on the region's matrix from guess_ into x; the iterations add up in stats
  void regionCg(const Eigen::VectorXd& b, Eigen::VectorXd& x, ElectricSolveStats& stats) {
    x = cg_.solveWithGuess(b, guess_);
    stats.iterations += static_cast<int>(cg_.iterations());
    stats.residual = std::max(stats.residual, cg_.error());
    ESIM_RUN_CHECK(x.allFinite() && cg_.error() <= options_.pcgTolerance,
                   "solve_potential: the local region's CG did not converge: relative residual " +
                       messageNumber(cg_.error()) + " after " + std::to_string(cg_.iterations()) +
                       " iterations, above solvers.electric.tolerance = " +
                       messageNumber(options_.pcgTolerance) +
                       "; raise solvers.electric.max_iterations or use pcg");
  }

  // what an inner solver has not taken yet of the matrix's changes since it last took one
  struct InnerChange {
    bool hasMatrix = false;         // it has taken a matrix since setMatrix (pcg's update
                                    // falls back to setMatrix itself where it must)
    bool told = true;               // every cut since came with its changed nodes
    std::vector<int> changedNodes;  // ... their union, ascending
    // one more cut
    void add(const std::vector<int>* changed) {
      if (!changed) {
        told = false;
        return;
      }
      std::vector<int> both;
      std::set_union(changedNodes.begin(), changedNodes.end(), changed->begin(), changed->end(),
                     std::back_inserter(both));
      changedNodes = std::move(both);
    }
    // nothing pending, a matrix taken
    static InnerChange taken() {
      InnerChange c;
      c.hasMatrix = true;
      return c;
    }
    // the matrix to the solver: updateMatrix when it has one, else setMatrix
    void give(ElectricSolver& solver, const SparseMatrix& K, const std::vector<int>& grounded) {
      if (hasMatrix)
        solver.updateMatrix(K, grounded, told ? &changedNodes : nullptr);
      else
        solver.setMatrix(K, grounded);
      *this = InnerChange::taken();
    }
  };

  ElectricSolverOptions options_;
  FreeBase free_;   // the node classes now (free_.current), edited in place by a cut
  SparseMatrix K_;  // the current matrix (the region side)
  std::vector<int> grounded_;
  bool pending_ = false;  // K_ not yet given to the full solver
  std::vector<Vec3> positions_;
  std::unique_ptr<ElectricSolver> full_;  // pcg; on the refresh thread while it runs
  std::unique_ptr<ElectricSolver> now_;   // pcg for the full solves in the frame
  bool nowPending_ = false;               // K_ not yet given to now_
  bool dropRefresh_ = false;              // the refresh in flight is of a place left since
  Eigen::VectorXd held_;                  // the far field [V] at heldVoltageV_
  double heldVoltageV_ = 0;
  std::vector<int> heldContact_;  // the contact set of the held solve
  int solves_ = 0;                // solves with contact since the first full one
  int nextRefresh_ = 0;  // the solve count at which the next refresh is adopted and started
  std::future<void> refresh_;
  InnerChange fullChange_, nowChange_;  // what full_ and now_ have not taken yet
  SparseMatrix refreshK_;               // the refresh thread's copies
  std::vector<int> refreshGrounded_;
  InnerChange refreshChange_;
  Eigen::VectorXd refreshed_;
  double refreshedVoltageV_ = 0;
  std::vector<int> refreshedContact_;
  // the region's scratch, kept across frames
  std::vector<int> mark_, region_, queue_, centres_;
  Eigen::VectorXd uH_, kuH_, b1_, bH_, guess_, x1_, xH_;
  std::vector<Eigen::Triplet<double>> entries_;  // K_RR's entries
  std::unique_ptr<ElectricSolver> check_;        // localCheck's full solver
  Eigen::VectorXd checkU_;
  SparseMatrix A_;
  Eigen::ConjugateGradient<SparseMatrix, Eigen::Lower | Eigen::Upper,
                           Eigen::DiagonalPreconditioner<double>>
      cg_;
};

}  // namespace

std::unique_ptr<ElectricSolver> makeLocalSolver(const ElectricSolverOptions& options) {
  return std::make_unique<LocalSolver>(options);
}

}  // namespace esim::electric_detail
