// electric_solver.cpp - strategy names, factory and the parts the strategies share
// (node classes, reduced matrices, the CHOLMOD factorization). See electric_solver.h.
#include "sim/electric_solver.h"

#ifdef __linux__
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>
#endif

#include <cblas.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <climits>
#include <cmath>
#include <cstring>
#include <iterator>
#include <limits>
#include <string>
#include <utility>

#include "sim/cholmod_view.h"
#include "sim/core_error.h"
#include "sim/ldl_solve.h"
#include "sim/ldl_updown.h"
#include "sim/message_text.h"

namespace esim {

ElectricSolver::~ElectricSolver() = default;

ElectricUpdateStats ElectricSolver::updateMatrix(const SparseMatrix& K,
                                                 const std::vector<int>& grounded,
                                                 const std::vector<int>* /*changedNodes*/) {
  setMatrix(K, grounded);
  ElectricUpdateStats stats;
  stats.fellBack = true;
  stats.fallbackReason = std::string(name()) + " has no in-place update";
  return stats;
}

// ---- names ----

ElectricStrategy parseElectricStrategy(const std::string& name) {
  if (name == "refactor") return ElectricStrategy::Refactor;
  if (name == "dense-inverse") return ElectricStrategy::DenseInverse;
  if (name == "capacitance") return ElectricStrategy::Capacitance;
  if (name == "pcg") return ElectricStrategy::Pcg;
  if (name == "local") return ElectricStrategy::Local;
  if (name == "downdate") return ElectricStrategy::Downdate;
  if (name == "auto") return ElectricStrategy::Auto;
  throw Error("electric solver: unknown strategy " + quoteInMessage(name) +
              "; valid names: refactor, dense-inverse, capacitance, pcg, local, downdate, auto");
}

const char* electricStrategyName(ElectricStrategy strategy) {
  switch (strategy) {
    case ElectricStrategy::Refactor:
      return "refactor";
    case ElectricStrategy::DenseInverse:
      return "dense-inverse";
    case ElectricStrategy::Capacitance:
      return "capacitance";
    case ElectricStrategy::Pcg:
      return "pcg";
    case ElectricStrategy::Local:
      return "local";
    case ElectricStrategy::Downdate:
      return "downdate";
    case ElectricStrategy::Auto:
      return "auto";
  }
  return "?";
}

void validateElectricSolverOptions(const ElectricSolverOptions& options) {
  ESIM_VERIFY(options.threads >= 1, "solvers.electric.threads must be >= 1");
  ESIM_VERIFY(options.pcgTolerance > 0 && std::isfinite(options.pcgTolerance),
              "solvers.electric.tolerance must be a positive number");
  ESIM_VERIFY(options.pcgMaxIterations >= 1, "solvers.electric.max_iterations must be >= 1");
  ESIM_VERIFY(options.updateResidual > 0 && std::isfinite(options.updateResidual),
              "electric solver: updateResidual must be a positive number");
  ESIM_VERIFY(options.denseMemoryLimitBytes > 0,
              "solvers.electric.dense_memory_limit_mb must be > 0");
  ESIM_VERIFY(options.localMarginM > 0 && std::isfinite(options.localMarginM),
              "solvers.electric.local_margin_m must be a positive number of metres");
  ESIM_VERIFY(options.localRefreshFrames >= 1,
              "solvers.electric.local_refresh_frames must be >= 1");
}

ElectricStrategy resolveElectricStrategy(const ElectricSolverOptions& options, double freeNodes,
                                         bool cuts) {
  if (options.strategy != ElectricStrategy::Auto) return options.strategy;
  const bool denseFits = 8.0 * freeNodes * freeNodes <= options.denseMemoryLimitBytes;
  if (freeNodes <= kAutoDenseMaxFreeNodes && denseFits) return ElectricStrategy::DenseInverse;
  if (!cuts) return ElectricStrategy::Capacitance;
  return freeNodes <= kAutoDowndateMaxFreeNodes ? ElectricStrategy::Downdate
                                                : ElectricStrategy::Pcg;
}

std::unique_ptr<ElectricSolver> makeElectricSolver(const ElectricSolverOptions& options) {
  validateElectricSolverOptions(options);
  ESIM_CHECK(options.strategy != ElectricStrategy::Auto);  // resolveElectricStrategy first
  switch (options.strategy) {
    case ElectricStrategy::Refactor:
      return electric_detail::makeRefactorSolver(options);
    case ElectricStrategy::DenseInverse:
      return electric_detail::makeDenseInverseSolver(options);
    case ElectricStrategy::Capacitance:
      return electric_detail::makeCapacitanceSolver(options);
    case ElectricStrategy::Pcg:
      return electric_detail::makePcgSolver(options);
    case ElectricStrategy::Local:
      return electric_detail::makeLocalSolver(options);
    case ElectricStrategy::Downdate:
      return electric_detail::makeDowndateSolver(options);
    case ElectricStrategy::Auto:
      break;
  }
  throw Error("electric solver: bad strategy value");
}

void setBlasThreads(int threads) { openblas_set_num_threads(std::max(1, threads)); }

void deprioritizeThisThread() {
#ifdef __linux__
  setpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)), 10);
#endif
}

namespace electric_detail {

// ---- node classes ----

namespace {

const char* const kNotFinite =
    "electric solver: the stiffness matrix has a non-finite entry (a NaN or infinite "
    "conductivity?)";

void verifySquare(const SparseMatrix& K) {
  ESIM_VERIFY(K.rows() == K.cols(), "electric solver: the stiffness matrix must be square");
}

void verifyGrounded(const std::vector<int>& grounded, int n) {
  ESIM_VERIFY(!grounded.empty(),
              "electric solver: no grounded node (the return electrode touches no mesh node); "
              "the potential would be undefined");
  for (size_t k = 0; k < grounded.size(); ++k) {
    const int g = grounded[k];
    ESIM_VERIFY(g >= 0 && g < n, "electric solver: grounded node id " + std::to_string(g) +
                                     " out of range [0, " + std::to_string(n) + ")");
    ESIM_VERIFY(k == 0 || grounded[k - 1] < g,
                "electric solver: grounded node ids must be sorted and unique");
  }
}

}  // namespace

void NodeClasses::build(const SparseMatrix& K, const std::vector<int>& grounded,
                        std::vector<int>* towardGround) {
  verifySquare(K);
  n = static_cast<int>(K.rows());
  for (Eigen::Index k = 0; k < K.nonZeros(); ++k)
    ESIM_VERIFY(std::isfinite(K.valuePtr()[k]), kNotFinite);
  verifyGrounded(grounded, n);
  isGrounded.assign(n, 0);
  for (int g : grounded) isGrounded[g] = 1;
  this->grounded = grounded;
  // breadth-first search from the grounded nodes over the nonzeros of K
  std::vector<std::uint8_t> reached(n, 0);
  std::vector<int> queue(grounded.begin(), grounded.end());
  for (int g : grounded) reached[g] = 1;
  if (towardGround) towardGround->assign(n, -1);
  for (size_t head = 0; head < queue.size(); ++head) {
    const int j = queue[head];
    for (SparseMatrix::InnerIterator it(K, j); it; ++it) {
      const int i = static_cast<int>(it.row());
      if (!reached[i] && it.value() != 0.0) {
        reached[i] = 1;
        queue.push_back(i);
        if (towardGround) (*towardGround)[i] = j;
      }
    }
  }
  freeNodes.clear();
  freeIndex.assign(n, -1);
  for (int i = 0; i < n; ++i) {
    if (reached[i] && !isGrounded[i]) {
      freeIndex[i] = static_cast<int>(freeNodes.size());
      freeNodes.push_back(i);
    }
  }
}

namespace {

// checks contact (sorted, in range, not grounded) and returns freeIndex of its free nodes
std::vector<int> contactIndices(const std::vector<int>& contact, int n,
                                const std::vector<std::uint8_t>& isGrounded,
                                const std::vector<int>& freeIndex) {
  std::vector<int> out;
  out.reserve(contact.size());
  for (size_t k = 0; k < contact.size(); ++k) {
    const int c = contact[k];
    ESIM_VERIFY(c >= 0 && c < n, "electric solver: contact node id " + std::to_string(c) +
                                     " out of range [0, " + std::to_string(n) + ")");
    ESIM_VERIFY(k == 0 || contact[k - 1] < c,
                "electric solver: contact node ids must be sorted and unique");
    ESIM_VERIFY(!isGrounded[c], "electric solver: short circuit: the tool touches node " +
                                    std::to_string(c) +
                                    ", which belongs to the return electrode (grounded)");
    if (freeIndex[c] >= 0) out.push_back(freeIndex[c]);
  }
  return out;
}

}  // namespace

std::vector<int> NodeClasses::contactFreeIndices(const std::vector<int>& contact) const {
  return contactIndices(contact, n, isGrounded, freeIndex);
}

SparseMatrix restrictToFree(const SparseMatrix& K, const NodeClasses& classes) {
  const int nf = classes.numFree();
  SparseMatrix A(nf, nf);
  std::vector<int> counts(nf, 0);
  for (int jf = 0; jf < nf; ++jf) {
    for (SparseMatrix::InnerIterator it(K, classes.freeNodes[jf]); it; ++it)
      if (classes.freeIndex[it.row()] >= 0) ++counts[jf];
  }
  A.reserve(counts);
  for (int jf = 0; jf < nf; ++jf) {
    for (SparseMatrix::InnerIterator it(K, classes.freeNodes[jf]); it; ++it) {
      const int i = classes.freeIndex[it.row()];
      if (i >= 0) A.insert(i, jf) = it.value();  // rows ascend: freeIndex is monotone
    }
  }
  A.makeCompressed();
  return A;
}

// ---- base index space ----

void FreeBase::set(const SparseMatrix& K, const std::vector<int>& grounded) {
  current = CurrentClasses{};
  base.build(K, grounded, &towardGround);
  matrix = restrictToFree(K, base);
  active.assign(base.numFree(), 1);
  mark.assign(base.n, 0);
  walked.assign(base.n, 0);
  position.assign(base.numFree(), -1);
  epoch = walks = 0;
  current.n = base.n;
  current.freeIndex = base.freeIndex;  // the base indices are the free indices now
  current.isGrounded = base.isGrounded;
  current.grounded = base.grounded;
  current.freeCount = base.numFree();
}

BaseChange FreeBase::diff(const SparseMatrix& K, const std::vector<int>& grounded,
                          const std::vector<int>* changed) const {
  if (changed) {
    BaseChange ch;
    if (diffNear(K, grounded, *changed, ch)) return ch;
  }
  return diffAll(K, grounded);
}

namespace {

// the entries of the base matrix's column j whose bits change to `values` (its new values,
// in its storage order from `first`), into ch (positions, values, the delta's triplets), and
// the rows staying free that the change touches
template <class Stays>
void recordColumn(const SparseMatrix& matrix, int j, const double* values, int first,
                  const Stays& stays, BaseChange& ch, std::vector<Eigen::Triplet<double>>& delta,
                  std::vector<int>& touched) {
  const int* outer = matrix.outerIndexPtr();
  const int* inner = matrix.innerIndexPtr();
  const double* old = matrix.valuePtr();
  for (int p = outer[j]; p < outer[j + 1]; ++p) {
    const double v = values[p - first];
    if (std::memcmp(&v, &old[p], sizeof v) != 0) {
      ch.positions.push_back(p);
      ch.values.push_back(v);
    }
    const int i = inner[p];
    const double d = v - old[p];
    if (d != 0.0) {
      delta.emplace_back(i, j, d);
      if (stays(i) && stays(j)) {
        touched.push_back(i);
        touched.push_back(j);
      }
    }
  }
}

// the grounded ids, and those joining and leaving the ground against the current ones
void groundChange(const std::vector<int>& grounded, const std::vector<int>& now, BaseChange& ch) {
  ch.grounded = grounded;
  std::set_difference(grounded.begin(), grounded.end(), now.begin(), now.end(),
                      std::back_inserter(ch.groundJoined));
  std::set_difference(now.begin(), now.end(), grounded.begin(), grounded.end(),
                      std::back_inserter(ch.groundLeft));
}

}  // namespace

BaseChange FreeBase::diffAll(const SparseMatrix& K, const std::vector<int>& grounded) const {
  BaseChange ch;
  std::vector<int> forest;
  NodeClasses nc;
  nc.build(K, grounded, &forest);
  if (nc.n == base.n) towardGround = std::move(forest);  // a fresh guide
  if (nc.n != base.n) {
    ch.fallback = "the node count changed";
    return ch;
  }
  for (int i = 0; i < base.n; ++i) {
    if (nc.freeIndex[i] >= 0 && current.freeIndex[i] < 0) {
      ch.fallback = "node " + std::to_string(i) + " joined the free set";
      return ch;
    }
  }
  groundChange(grounded, current.grounded, ch);
  const int m = size();
  std::vector<std::uint8_t> stayed(m, 0);
  for (int b = 0; b < m; ++b) {
    stayed[b] = nc.freeIndex[base.freeNodes[b]] >= 0;
    if (active[b] && !stayed[b]) ch.dropped.push_back(b);
  }
  const auto stays = [&stayed](int b) { return stayed[b] != 0; };
  std::vector<Eigen::Triplet<double>> delta;
  std::vector<int> touched;
  std::vector<double> column;
  for (int j = 0; j < m; ++j) {
    newColumn(K, j, stays, column, ch.fallback);
    recordColumn(matrix, j, column.data(), matrix.outerIndexPtr()[j], stays, ch, delta, touched);
  }
  if (!ch.fallback.empty()) return ch;
  finishChange(m, delta, touched, ch);
  return ch;
}

// the new values of the base matrix's column j (in its storage order) given which base
// indices stay free: K's entries between nodes still free, identity rows and columns for the
// others; a nonzero of K_ff outside the base pattern sets `fallback`
template <class Stays>
void FreeBase::newColumn(const SparseMatrix& K, int j, const Stays& stays,
                         std::vector<double>& column, std::string& fallback) const {
  const int* outer = matrix.outerIndexPtr();
  const int* inner = matrix.innerIndexPtr();
  const int first = outer[j], count = outer[j + 1] - first;
  column.assign(count, 0.0);
  for (int p = 0; p < count; ++p) position[inner[first + p]] = p;
  if (!stays(j)) {
    ESIM_CHECK(position[j] >= 0);  // restrictToFree keeps the diagonal of a free node
    column[position[j]] = 1.0;
  } else {
    for (SparseMatrix::InnerIterator it(K, base.freeNodes[j]); it; ++it) {
      const int b = base.freeIndex[it.row()];
      if (b < 0 || !stays(b)) continue;
      if (position[b] < 0) {
        if (it.value() != 0.0 && fallback.empty())
          fallback = "K_ff gained a nonzero outside the pattern of the last setMatrix";
        continue;
      }
      column[position[b]] = it.value();
    }
  }
  for (int p = 0; p < count; ++p) position[inner[first + p]] = -1;
}

// the delta from its triplets, the touched rows ascending. The triplets come column by
// column, rows ascending (recordColumn over ascending columns): the compressed delta is then
// written directly, one pass over its column index (Eigen's setFromTriplets makes several
// over m-sized arrays: 0.91 ms of a told update's 1.07 ms at 150 528 nodes, a temporary
// timer; esim bench electric --only-update)
void FreeBase::finishChange(int m, std::vector<Eigen::Triplet<double>>& delta,
                            std::vector<int>& touched, BaseChange& ch) {
  ch.delta.resize(m, m);
  const auto before = [](const Eigen::Triplet<double>& a, const Eigen::Triplet<double>& b) {
    return a.col() < b.col() || (a.col() == b.col() && a.row() < b.row());
  };
  bool ordered = true;
  for (size_t k = 1; k < delta.size() && ordered; ++k) ordered = before(delta[k - 1], delta[k]);
  if (ordered) {
    const int nnz = static_cast<int>(delta.size());
    ch.delta.resizeNonZeros(nnz);
    int* outer = ch.delta.outerIndexPtr();
    int* inner = ch.delta.innerIndexPtr();
    double* values = ch.delta.valuePtr();
    int k = 0;
    for (int j = 0; j < m; ++j) {
      outer[j] = k;
      for (; k < nnz && delta[k].col() == j; ++k) {
        inner[k] = delta[k].row();
        values[k] = delta[k].value();
      }
    }
    outer[m] = k;
    ESIM_CHECK(k == nnz);  // every column in [0, m)
  } else {
    ch.delta.setFromTriplets(delta.begin(), delta.end());
  }
  std::sort(touched.begin(), touched.end());
  touched.erase(std::unique(touched.begin(), touched.end()), touched.end());
  ch.touched = std::move(touched);
}

// The change from the changed nodes (a cut: the removed elements' nodes). Every edge K
// lost joins two changed nodes, so a node cut off from the ground is in the component of a
// changed node: a node whose path to the ground (the forest) crossed a removed edge reaches,
// along the part of that path still there, an endpoint of one. Each changed node free now
// is followed up its forest path; a path that ends on a grounded node over nonzeros of K
// marks its nodes connected, else a breadth-first search from the node runs until a node
// whose path holds (that branch of the forest then goes through it) or until its component
// is exhausted (floating). The matrix's columns of the changed nodes, of the nodes leaving
// the free set and of their neighbours are then made as diffAll makes them. The O(nnz) way
// is taken where that reasoning needs more than a removal gives: a changed column that
// joins a node outside the free set to another, a node leaving the ground that keeps an
// element, a floating node newly grounded that has one, or a search past a quarter of
// nnz(K) (a cut that undercuts much of the forest).
bool FreeBase::diffNear(const SparseMatrix& K, const std::vector<int>& grounded,
                        const std::vector<int>& changed, BaseChange& ch) const {
  verifySquare(K);
  const int n = base.n;
  if (K.rows() != n || current.n != n) return false;  // diffAll names it
  for (size_t k = 0; k < changed.size(); ++k)
    ESIM_CHECK(changed[k] >= 0 && changed[k] < n && (k == 0 || changed[k - 1] < changed[k]));
  verifyGrounded(grounded, n);
  for (int c : changed)
    for (SparseMatrix::InnerIterator it(K, c); it; ++it)
      ESIM_VERIFY(std::isfinite(it.value()), kNotFinite);
  const auto entry = [&](int i, int j) {  // K(i, j), 0 where not stored
    const int* begin = K.innerIndexPtr() + K.outerIndexPtr()[j];
    const int* end = K.innerIndexPtr() + K.outerIndexPtr()[j + 1];
    const int* at = std::lower_bound(begin, end, i);
    return at != end && *at == i ? K.valuePtr()[at - K.innerIndexPtr()] : 0.0;
  };
  const auto linked = [&](int j) {  // a nonzero off the diagonal in K's column j
    for (SparseMatrix::InnerIterator it(K, j); it; ++it)
      if (it.row() != j && it.value() != 0.0) return true;
    return false;
  };

  // the ground's change (the classes now are read through it: nothing is copied)
  groundChange(grounded, current.grounded, ch);
  const std::vector<int>&joined = ch.groundJoined, &left = ch.groundLeft;
  const auto groundedNow = [&](int v) {
    return current.isGrounded[v] ? !std::binary_search(left.begin(), left.end(), v)
                                 : std::binary_search(joined.begin(), joined.end(), v);
  };
  for (int g : left)
    if (linked(g)) return false;
  for (int g : joined)
    if (current.freeIndex[g] < 0 && linked(g)) return false;
  const auto outside = [&](int v) { return current.freeIndex[v] < 0 && !groundedNow(v); };
  long work = 0;
  for (int c : changed)
    for (SparseMatrix::InnerIterator it(K, c); it; ++it) {
      ++work;
      if (it.row() != c && it.value() != 0.0 && (outside(c) || outside(it.row()))) return false;
    }

  // which changed nodes still reach the ground
  if (epoch >= std::numeric_limits<int>::max() / 4 - 1) {
    std::fill(mark.begin(), mark.end(), 0);
    epoch = 0;
  }
  ++epoch;
  const int connected = 4 * epoch + 1, floating = 4 * epoch + 2, searched = 4 * epoch + 3;
  const long budget = K.nonZeros() / 4 + 64;
  std::vector<int> path;
  // follows v's forest path: true when it ends on a grounded node over nonzeros of K
  const auto holds = [&](int v) {
    if (walks == std::numeric_limits<int>::max()) {
      std::fill(walked.begin(), walked.end(), 0);
      walks = 0;
    }
    ++walks;
    path.clear();
    bool ok = false;
    for (int x = v;; ++work) {
      if (groundedNow(x) || mark[x] == connected) {
        ok = true;
        break;
      }
      if (walked[x] == walks || mark[x] == floating) break;  // a loop: the guide is stale
      walked[x] = walks;
      path.push_back(x);
      const int up = towardGround[x];
      if (up < 0 || outside(up) || entry(x, up) == 0.0) break;
      x = up;
    }
    if (ok)
      for (int x : path) mark[x] = connected;
    return ok;
  };
  std::vector<std::pair<int, int>> queue;  // (node, its parent's place in the queue)
  std::vector<int> lost;                   // free nodes now floating
  for (int s : changed) {
    if (current.freeIndex[s] < 0 || groundedNow(s) || mark[s] == connected || mark[s] == floating ||
        holds(s))
      continue;
    queue.assign(1, {s, -1});
    mark[s] = searched;
    int found = -1, from = -1;
    for (size_t head = 0; head < queue.size() && found < 0; ++head) {
      const int x = queue[head].first;
      for (SparseMatrix::InnerIterator it(K, x); it; ++it) {
        const int i = static_cast<int>(it.row());
        if (++work > budget) return false;
        if (i == x || it.value() == 0.0 || mark[i] == searched) continue;
        if (holds(i)) {
          found = i;
          from = static_cast<int>(head);
          break;
        }
        mark[i] = searched;
        queue.emplace_back(i, static_cast<int>(head));
      }
    }
    if (found >= 0) {  // the branch of the forest from s goes through the search's path
      for (int k = from, up = found; k >= 0; up = queue[k].first, k = queue[k].second)
        towardGround[queue[k].first] = up;
      for (const auto& q : queue) mark[q.first] = connected;
    } else {
      for (const auto& q : queue) {
        mark[q.first] = floating;
        lost.push_back(q.first);
      }
    }
  }

  // the free nodes that leave: the floating and the newly grounded
  for (int v : lost)
    if (current.freeIndex[v] >= 0) ch.dropped.push_back(current.freeIndex[v]);
  for (int g : joined)
    if (current.freeIndex[g] >= 0) ch.dropped.push_back(current.freeIndex[g]);
  std::sort(ch.dropped.begin(), ch.dropped.end());
  ch.dropped.erase(std::unique(ch.dropped.begin(), ch.dropped.end()), ch.dropped.end());
  const auto stays = [&](int b) {
    const int v = base.freeNodes[b];
    return current.freeIndex[v] >= 0 && mark[v] != floating && !groundedNow(v);
  };

  // the columns that change: the changed nodes', the dropped ones' and their neighbours'
  const int m = size();
  std::vector<int> columns;
  for (int c : changed)
    if (base.freeIndex[c] >= 0) columns.push_back(base.freeIndex[c]);
  for (int d : ch.dropped)
    for (SparseMatrix::InnerIterator it(matrix, d); it; ++it)
      columns.push_back(static_cast<int>(it.row()));
  std::sort(columns.begin(), columns.end());
  columns.erase(std::unique(columns.begin(), columns.end()), columns.end());
  std::vector<Eigen::Triplet<double>> delta;
  std::vector<int> touched;
  std::vector<double> column;
  for (int j : columns) {
    newColumn(K, j, stays, column, ch.fallback);
    recordColumn(matrix, j, column.data(), matrix.outerIndexPtr()[j], stays, ch, delta, touched);
  }
  if (ch.fallback.empty()) finishChange(m, delta, touched, ch);
  return true;
}

double FreeBase::identityResidual(const std::vector<int>& rows, const Eigen::MatrixXd& y) const {
  if (rows.empty()) return 0.0;
  Eigen::MatrixXd r = matrix * y;
  for (size_t k = 0; k < rows.size(); ++k) r(rows[k], k) -= 1.0;
  return r.norm() / std::sqrt(static_cast<double>(rows.size()));
}

void FreeBase::apply(const BaseChange& change) {
  ESIM_CHECK(change.fallback.empty() && change.values.size() == change.positions.size());
  current.grounded = change.grounded;
  for (int g : change.groundJoined) current.isGrounded[g] = 1;
  for (int g : change.groundLeft) current.isGrounded[g] = 0;
  for (int d : change.dropped) {
    ESIM_CHECK(active[d]);
    current.freeIndex[base.freeNodes[d]] = -1;
    active[d] = 0;
  }
  current.freeCount -= static_cast<int>(change.dropped.size());
  double* values = matrix.valuePtr();
  for (size_t k = 0; k < change.positions.size(); ++k)
    values[change.positions[k]] = change.values[k];
}

std::vector<int> FreeBase::contactBaseIndices(const std::vector<int>& contact) const {
  return contactIndices(contact, current.n, current.isGrounded, current.freeIndex);
}

std::vector<int> FreeBase::contactsOrZero(const std::vector<int>& contact,
                                          Eigen::VectorXd& potential) const {
  ESIM_CHECK(current.n > 0);  // setMatrix before solve
  std::vector<int> cf = contactBaseIndices(contact);
  if (cf.empty()) potential.setZero(current.n);
  return cf;
}

void FreeBase::scatter(const Eigen::VectorXd& baseValues, const std::vector<int>& contactBase,
                       double voltageV, Eigen::VectorXd& potential) const {
  potential.setZero(base.n);
  for (int b = 0; b < size(); ++b)
    if (active[b]) potential[base.freeNodes[b]] = baseValues[b];
  for (int c : contactBase) potential[base.freeNodes[c]] = voltageV;
}

ElectricUpdateStats updateFreeBase(FreeBase& free, const SparseMatrix& K,
                                   const std::vector<int>& grounded,
                                   const std::vector<int>* changedNodes, BaseChange& change,
                                   const std::function<void()>& setMatrix) {
  ESIM_CHECK(free.current.n > 0);  // setMatrix before updateMatrix
  change = free.diff(K, grounded, changedNodes);
  ElectricUpdateStats stats;
  if (!change.fallback.empty()) {
    setMatrix();
    stats.fellBack = true;
    stats.fallbackReason = change.fallback;
    return stats;
  }
  stats.changedNodes = static_cast<int>(change.touched.size());
  stats.droppedNodes = static_cast<int>(change.dropped.size());
  free.apply(change);  // (an empty one may still move the ground: a floating node grounded)
  return stats;
}

void combineColumns(const std::vector<const double*>& z, const std::vector<int>& cf,
                    double voltageV, int nf, const char* what, Eigen::VectorXd& u) {
  const int c = static_cast<int>(cf.size());
  Eigen::MatrixXd zcc(c, c);
  for (int k = 0; k < c; ++k)
    for (int i = 0; i < c; ++i) zcc(i, k) = z[k][cf[i]];
  Eigen::LLT<Eigen::MatrixXd> llt(zcc);
  ESIM_VERIFY(llt.info() == Eigen::Success, std::string(what) + ": Z_cc is not positive definite");
  const Eigen::VectorXd f = llt.solve(Eigen::VectorXd::Constant(c, voltageV));
  u.setZero(nf);
  for (int k = 0; k < c; ++k) cblas_daxpy(nf, f[k], z[k], 1, u.data(), 1);
}

void scatterPotential(const NodeClasses& classes, const Eigen::VectorXd& freeValues,
                      const std::vector<int>& contactFree, double voltageV,
                      Eigen::VectorXd& potential) {
  potential.setZero(classes.n);
  for (int i = 0; i < classes.numFree(); ++i) potential[classes.freeNodes[i]] = freeValues[i];
  for (int c : contactFree) potential[classes.freeNodes[c]] = voltageV;
}

void dirichletSystem(const SparseMatrix& Kff, const std::vector<int>& contactFree, double voltageV,
                     SparseMatrix& A, Eigen::VectorXd& b) {
  const int nf = static_cast<int>(Kff.rows());
  std::vector<std::uint8_t> isContact(nf, 0);
  for (int c : contactFree) isContact[c] = 1;
  b.setZero(nf);
  const int* outer = Kff.outerIndexPtr();
  const int* inner = Kff.innerIndexPtr();
  const double* kv = Kff.valuePtr();
  double* av = A.valuePtr();
  for (int j = 0; j < nf; ++j) {
    for (int p = outer[j]; p < outer[j + 1]; ++p) {
      const int i = inner[p];
      if (isContact[j] || isContact[i]) {
        av[p] = (i == j) ? 1.0 : 0.0;
        if (isContact[j] && !isContact[i]) b[i] -= kv[p] * voltageV;
      } else {
        av[p] = kv[p];
      }
    }
  }
  for (int c : contactFree) b[c] = voltageV;
}

// ---- CHOLMOD ----

struct CholmodFactor::Impl {
  cholmod_common common;
  cholmod_factor* factor = nullptr;
  cholmod_dense* x = nullptr;
  cholmod_dense* y = nullptr;
  cholmod_dense* e = nullptr;
  LdlUpdownWork updown;          // the vectorized update's workspace (ldl_updown.h)
  LdlSolveWork ldl;              // the simplicial factor's solve (ldl_solve.h)
  std::vector<int> inversePerm;  // the row of L of each row of A (made on use, per analysis)
  // the pivots: every one was checked positive since the factorization (pivotsChecked),
  // but those on the paths up the elimination tree from pivotStarts (rows of L), which the
  // updates since may have changed (an update changes the columns on the path from each
  // column's first row, in L as it leaves it)
  bool pivotsChecked = false;
  std::vector<int> pivotStarts, pivotMark;
  int pivotStamp = 0;

  const std::vector<int>& rowOfL() {
    if (inversePerm.empty()) {
      const int* perm = static_cast<const int*>(factor->Perm);
      inversePerm.resize(factor->n);
      for (int k = 0; k < static_cast<int>(factor->n); ++k) inversePerm[perm[k]] = k;
    }
    return inversePerm;
  }
};

CholmodFactor::CholmodFactor() : impl_(new Impl) {
  cholmod_start(&impl_->common);
  impl_->common.supernodal = CHOLMOD_SUPERNODAL;
  impl_->common.print = 0;
  impl_->common.error_handler = nullptr;
}

CholmodFactor::~CholmodFactor() {
  cholmod_common* c = &impl_->common;
  if (impl_->factor) cholmod_free_factor(&impl_->factor, c);
  if (impl_->x) cholmod_free_dense(&impl_->x, c);
  if (impl_->y) cholmod_free_dense(&impl_->y, c);
  if (impl_->e) cholmod_free_dense(&impl_->e, c);
  cholmod_finish(c);
  delete impl_;
}

void CholmodFactor::analyze(const SparseMatrix& A) { analyze(A, {}); }

void CholmodFactor::analyze(const SparseMatrix& A, const std::vector<int>& ordering) {
  ESIM_CHECK(A.isCompressed() &&
             (ordering.empty() || static_cast<int>(ordering.size()) == A.rows()));
  cholmod_common* c = &impl_->common;
  if (impl_->factor) cholmod_free_factor(&impl_->factor, c);
  factorized_ = false;
  impl_->inversePerm.clear();
  cholmod_sparse s = cholmodViewLower(A);
  std::vector<int> perm(ordering);  // CHOLMOD takes a non-const pointer
  impl_->factor = perm.empty() ? cholmod_analyze(&s, c) : cholmodAnalyzeGiven(&s, perm.data(), c);
  if (impl_->factor == nullptr) throwIfOutOfResources(*c);
  ESIM_RUN_CHECK(impl_->factor != nullptr, "electric solver: CHOLMOD symbolic analysis failed");
  factorizeFlops_ = c->fl;
}

std::vector<int> CholmodFactor::ordering() const {
  if (!impl_->factor) return {};
  const int* perm = static_cast<const int*>(impl_->factor->Perm);
  return std::vector<int>(perm, perm + impl_->factor->n);
}

void CholmodFactor::factorize(const SparseMatrix& A, const char* what) {
  ESIM_CHECK(impl_->factor != nullptr);  // analyze before factorize
  cholmod_common* c = &impl_->common;
  cholmod_sparse s = cholmodViewLower(A);
  const int ok = cholmod_factorize(&s, impl_->factor, c);
  impl_->pivotsChecked = false;
  impl_->pivotStarts.clear();
  throwIfOutOfResources(*c);
  factorized_ = ok && c->status == CHOLMOD_OK && impl_->factor->minor == impl_->factor->n;
  ESIM_RUN_CHECK(factorized_, std::string(what) +
                                  ": the matrix is not positive definite (CHOLMOD status " +
                                  std::to_string(c->status) + ", column " +
                                  std::to_string(impl_->factor->minor) +
                                  "); a conductivity <= 0 or a NaN in K?");
}

void CholmodFactor::solve(const double* b, double* x, int ncols) {
  ESIM_CHECK(factorized_);  // solve after a successful factorization
  cholmod_common* c = &impl_->common;
  const int n = size();
  if (ncols == 1 && ldlSolveSupports(*impl_->factor)) {  // simplicial LDL': one thread
    ldlSolve(*impl_->factor, b, x, 1, impl_->ldl);
    return;
  }
  cholmod_dense bd = cholmodViewDense(b, n, ncols);
  const int ok = cholmod_solve2(CHOLMOD_A, impl_->factor, &bd, nullptr, &impl_->x, nullptr,
                                &impl_->y, &impl_->e, c);
  if (!ok) throwIfOutOfResources(*c);
  ESIM_RUN_CHECK(ok, "electric solver: CHOLMOD solve failed");
  std::copy_n(static_cast<const double*>(impl_->x->x), static_cast<size_t>(n) * ncols, x);
}

void CholmodFactor::solveBackward(const double* y, double* x) {
  ESIM_CHECK(factorized_ && ldlSolveSupports(*impl_->factor));  // a simplicial LDL' factor
  ldlSolveBackward(*impl_->factor, y, x, 1, impl_->ldl);
}

void CholmodFactor::toSimplicial() {
  ESIM_CHECK(factorized_);
  cholmod_factor* f = impl_->factor;
  if (!f->is_super && !f->is_ll) return;
  // simplicial LDL', not packed (room for fill), not monotonic
  const int ok = cholmod_change_factor(CHOLMOD_REAL, false, false, false, false, f, &impl_->common);
  throwIfOutOfResources(impl_->common);
  ESIM_RUN_CHECK(ok && !f->is_super && !f->is_ll,
                 "electric solver: CHOLMOD could not convert the factor to LDL'");
}

bool CholmodFactor::isSupernodal() const { return impl_->factor && impl_->factor->is_super; }

void CholmodFactor::deleteRow(int i) {
  toSimplicial();
  cholmod_factor* f = impl_->factor;
  const int* perm = static_cast<const int*>(f->Perm);
  int k = 0;
  while (k < static_cast<int>(f->n) && perm[k] != i) ++k;
  ESIM_CHECK(k < static_cast<int>(f->n));
  const int ok = cholmod_rowdel(k, nullptr, f, &impl_->common);
  impl_->pivotsChecked = false;  // (rowdel's columns: not followed here)
  if (!ok) throwIfOutOfResources(impl_->common);
  ESIM_RUN_CHECK(ok, "electric solver: CHOLMOD rowdel failed (status " +
                         std::to_string(impl_->common.status) + ")");
}

void CholmodFactor::updateDowndate(bool update, const SparseMatrix& C) {
  toSimplicial();
  cholmod_factor* f = impl_->factor;
  const int n = static_cast<int>(f->n);
  ESIM_CHECK(C.rows() == n);
  if (C.cols() == 0) return;
  // rows of C in the order of L: row i of A is row inversePerm[i] of L
  const std::vector<int>& inversePerm = impl_->rowOfL();
  std::vector<Eigen::Triplet<double>> t;
  t.reserve(C.nonZeros());
  for (int j = 0; j < C.cols(); ++j)
    for (SparseMatrix::InnerIterator it(C, j); it; ++it)
      t.emplace_back(inversePerm[it.row()], j, it.value());
  SparseMatrix permuted(n, C.cols());
  permuted.setFromTriplets(t.begin(), t.end());  // compressed, rows sorted
  cholmod_sparse cs = cholmodViewLower(permuted);
  cs.stype = 0;  // unsymmetric n x r
  for (int j = 0; j < permuted.cols(); ++j)
    if (permuted.outerIndexPtr()[j] < permuted.outerIndexPtr()[j + 1])
      impl_->pivotStarts.push_back(permuted.innerIndexPtr()[permuted.outerIndexPtr()[j]]);
  const int ok = ldlUpdown(update, cs, *f, impl_->updown, impl_->common);
  if (!ok) throwIfOutOfResources(impl_->common);
  ESIM_RUN_CHECK(ok, "electric solver: CHOLMOD update/downdate failed (status " +
                         std::to_string(impl_->common.status) + ")");
}

bool CholmodFactor::deleteRows(const std::vector<int>& indices, const SparseMatrix& A) {
  toSimplicial();
  cholmod_factor* f = impl_->factor;
  const int n = static_cast<int>(f->n);
  ESIM_CHECK(A.rows() == n && A.cols() == n);
  if (indices.empty()) return true;
  const int* perm = static_cast<const int*>(f->Perm);
  const std::vector<int>& inversePerm = impl_->rowOfL();
  std::vector<int> rows;
  for (int i : indices) rows.push_back(inversePerm[i]);
  std::sort(rows.begin(), rows.end());
  std::vector<int> from, wp, wi;
  std::vector<double> wx;
  const auto subtree = [&](int k, std::vector<int>& out) {
    from.clear();
    for (SparseMatrix::InnerIterator it(A, perm[k]); it; ++it)
      if (inversePerm[it.row()] < k) from.push_back(inversePerm[it.row()]);
    ldlRowSubtree(*f, k, from.data(), static_cast<int>(from.size()), impl_->updown, out);
  };
  if (!ldlTakeRows(rows, subtree, *f, wp, wi, wx)) return false;
  impl_->pivotStarts.insert(impl_->pivotStarts.end(), rows.begin(), rows.end());
  for (size_t c = 0; c + 1 < wp.size(); ++c)
    if (wp[c] < wp[c + 1]) impl_->pivotStarts.push_back(wi[wp[c]]);
  if (wp.size() == 1) return true;
  cholmod_sparse w = cholmodViewColumns(f->n, wp.size() - 1, wp.data(), wi.data(), wx.data());
  const int ok = ldlUpdown(true, w, *f, impl_->updown, impl_->common);
  if (!ok) throwIfOutOfResources(impl_->common);
  ESIM_RUN_CHECK(ok, "electric solver: the rows' update failed (CHOLMOD status " +
                         std::to_string(impl_->common.status) + ")");
  return true;
}

// every pivot once after a factorization (O(n), each a cache line of its own); after that
// those on the paths the updates since walked (O(the change): a removal's update no longer
// reads the whole factor for its check)
bool CholmodFactor::pivotsPositive() const {
  const cholmod_factor* f = impl_->factor;
  if (!f || f->is_super || f->is_ll) return factorized_;
  const int n = static_cast<int>(f->n);
  const int* p = static_cast<const int*>(f->p);
  const int* i = static_cast<const int*>(f->i);
  const int* nz = static_cast<const int*>(f->nz);
  const double* x = static_cast<const double*>(f->x);
  const auto positive = [&](int j) {
    const double d = x[p[j]];  // the diagonal comes first in each column
    return d > 0.0 && std::isfinite(d);
  };
  Impl& m = *impl_;
  if (!m.pivotsChecked) {
    for (int j = 0; j < n; ++j)
      if (!positive(j)) return false;
    m.pivotsChecked = true;
    m.pivotStarts.clear();
    return true;
  }
  if (static_cast<int>(m.pivotMark.size()) != n || m.pivotStamp == INT_MAX) {
    m.pivotMark.assign(n, 0);
    m.pivotStamp = 0;
  }
  const int stamp = ++m.pivotStamp;
  for (int start : m.pivotStarts)
    for (int j = start; j >= 0 && m.pivotMark[j] != stamp; j = nz[j] > 1 ? i[p[j] + 1] : -1) {
      m.pivotMark[j] = stamp;
      if (!positive(j)) return false;  // (the starts kept: asked again, the same answer)
    }
  m.pivotStarts.clear();
  return true;
}

double CholmodFactor::factorEntries() const {
  const cholmod_factor* f = impl_->factor;
  if (!f) return 0;
  if (f->is_super) return static_cast<double>(f->xsize);
  const int* nz = static_cast<const int*>(f->nz);
  double entries = 0;
  for (size_t j = 0; j < f->n; ++j) entries += nz[j];
  return entries;
}

void CholmodFactor::swap(CholmodFactor& other) {
  std::swap(impl_, other.impl_);
  std::swap(factorized_, other.factorized_);
  std::swap(factorizeFlops_, other.factorizeFlops_);
}

const cholmod_factor& CholmodFactor::cholmod() const {
  ESIM_CHECK(impl_->factor != nullptr);  // analyze first
  return *impl_->factor;
}

int CholmodFactor::size() const { return impl_->factor ? static_cast<int>(impl_->factor->n) : 0; }

double CholmodFactor::memoryBytes() const {
  const cholmod_factor* f = impl_->factor;
  if (!f) return 0;
  double bytes = 8.0 * static_cast<double>(f->xsize) + 4.0 * static_cast<double>(f->n) * 3;
  if (f->is_super)
    bytes += 4.0 * static_cast<double>(f->ssize + 4 * f->nsuper);
  else
    bytes += 4.0 * static_cast<double>(f->nzmax + 4 * f->n);
  return bytes;
}

}  // namespace electric_detail
}  // namespace esim
