// The two-thread LDL' solve of ldl_solve.h: the plan (which columns each thread solves, in
// chains of up to eight), the forward solve L w = P b, and the backward solve
// L' x = D^-1 w, in place in one array; x = P' w.
#include "sim/ldl_solve.h"

#include <algorithm>
#include <functional>
#include <queue>
#include <utility>

#include "sim/two_threads.h"

namespace esim {
namespace {

constexpr int kMaxChain = 8;       // columns whose row indices (and scattered rows) one pass takes
constexpr double kBalance = 0.55;  // the heavier thread's share of the subtrees' work at most
constexpr double kMaxTop = 0.5;    // stop splitting once the top holds this share of the work

struct View {
  int n;
  const int* p;
  const int* i;
  const int* nz;
  const double* x;
  const int* perm;
  explicit View(const cholmod_factor& l)
      : n(static_cast<int>(l.n)),
        p(static_cast<const int*>(l.p)),
        i(static_cast<const int*>(l.i)),
        nz(static_cast<const int*>(l.nz)),
        x(static_cast<const double*>(l.x)),
        perm(static_cast<const int*>(l.Perm)) {}
};

}  // namespace

// one run of columns [start, start + count) of one owner; rows above `limit` are top rows
// (the forward solve of a subtree adds into its own array there)
struct LdlChain {
  int start, count, limit;
};

namespace {

// the subtrees left after taking `top` columns off: dealt to two bins, largest first to the
// lighter; returns the heavier bin's work
long deal(const std::vector<std::pair<long, int>>& roots, std::vector<int>* binOf,
          const std::vector<int>* index) {
  std::vector<std::pair<long, int>> sorted(roots);
  std::sort(sorted.begin(), sorted.end(), std::greater<>());
  long bin[2] = {0, 0};
  for (const auto& [w, s] : sorted) {
    const int b = bin[1] < bin[0] ? 1 : 0;
    bin[b] += w;
    if (binOf) (*binOf)[(*index)[s]] = b;
  }
  return std::max(bin[0], bin[1]);
}

}  // namespace

struct LdlSolvePlan {
  std::vector<int> keyNz, keyParent;  // the pattern the plan was made for ...
  long minSplitEntries = 0;           // ... and the minimum asked
  std::vector<LdlChain> chains[3];    // thread 0, thread 1, the top (ascending)
  std::vector<int> topRows;
  long work[3] = {};
  bool split = false;
};

bool ldlSolveSupports(const cholmod_factor& l) {
  return !l.is_super && !l.is_ll && l.itype == CHOLMOD_INT && l.xtype == CHOLMOD_REAL &&
         l.dtype == CHOLMOD_DOUBLE && l.n > 0;
}

namespace {

void makePlan(const View& l, long minSplitEntries, LdlSolvePlan& plan) {
  const int n = l.n;
  std::vector<int> parent(n, -1);
  std::vector<long> sub(n, 0);
  long total = 0;
  for (int j = 0; j < n; ++j) {
    if (l.nz[j] > 1) parent[j] = l.i[l.p[j] + 1];
    sub[j] += l.nz[j];
    total += l.nz[j];
    if (parent[j] >= 0) sub[parent[j]] += sub[j];
  }
  plan.keyNz.assign(l.nz, l.nz + n);
  plan.keyParent = parent;
  // owner: 0 / 1 a thread's subtree, 2 the top; subRoot: the root of a column's subtree
  std::vector<int> owner(n, -1), subRoot(n, n);
  plan.split = total >= minSplitEntries;
  if (!plan.split) {
    owner.assign(n, 0);
  } else {
    // children lists
    std::vector<int> start(n + 1, 0), child(n);
    for (int j = 0; j < n; ++j)
      if (parent[j] >= 0) ++start[parent[j] + 1];
    for (int j = 0; j < n; ++j) start[j + 1] += start[j];
    std::vector<int> fill(start.begin(), start.end() - 1);
    for (int j = 0; j < n; ++j)
      if (parent[j] >= 0) child[fill[parent[j]]++] = j;
    // take the heaviest subtree off the top until the rest deals evenly
    std::priority_queue<std::pair<long, int>> heap;
    for (int j = 0; j < n; ++j)
      if (parent[j] < 0) heap.push({sub[j], j});
    long topWork = 0;
    std::vector<std::pair<long, int>> roots;
    const auto frontier = [&] {
      auto copy = heap;
      roots.clear();
      while (!copy.empty()) {
        roots.push_back(copy.top());
        copy.pop();
      }
    };
    while (!heap.empty()) {
      const int s = heap.top().second;
      // the deal is tried only where the tree branches (taking a chain's column changes it
      // little)
      if (start[s + 1] - start[s] != 1) {
        frontier();
        if (deal(roots, nullptr, nullptr) <= kBalance * static_cast<double>(total - topWork)) break;
      }
      if (start[s + 1] == start[s] || topWork > kMaxTop * static_cast<double>(total)) break;
      heap.pop();
      owner[s] = 2;
      topWork += l.nz[s];
      for (int c = start[s]; c < start[s + 1]; ++c) heap.push({sub[child[c]], child[c]});
    }
    frontier();
    std::vector<int> index(n, -1), binOf(roots.size());
    for (size_t k = 0; k < roots.size(); ++k) index[roots[k].second] = static_cast<int>(k);
    deal(roots, &binOf, &index);
    if (std::count(binOf.begin(), binOf.end(), 1) == 0) {  // nothing to share: one thread
      plan.split = false;
      owner.assign(n, 0);
    } else {
      for (size_t k = 0; k < roots.size(); ++k) {
        owner[roots[k].second] = binOf[k];
        subRoot[roots[k].second] = roots[k].second;
      }
      for (int j = n - 1; j >= 0; --j)
        if (owner[j] < 0) {  // below a subtree's root
          owner[j] = owner[parent[j]];
          subRoot[j] = subRoot[parent[j]];
        }
    }
  }
  for (auto& c : plan.chains) c.clear();
  plan.topRows.clear();
  std::fill(std::begin(plan.work), std::end(plan.work), 0);
  for (int j = 0; j < n;) {
    int c = 1;
    while (c < kMaxChain && j + c < n && parent[j + c - 1] == j + c &&
           l.nz[j + c] == l.nz[j + c - 1] - 1 && owner[j + c] == owner[j])
      ++c;
    const int o = owner[j];
    plan.chains[o].push_back({j, c, o == 2 ? n : subRoot[j]});
    for (int m = 0; m < c; ++m) {
      plan.work[o] += l.nz[j + m];
      if (o == 2) plan.topRows.push_back(j + m);
    }
    j += c;
  }
}

// forward: w = L^-1 w over one owner's chains; rows above a chain's limit go to acc
template <int C>
void forwardChain(const View& l, const LdlChain& ch, double* w, double* acc) {
  const int j = ch.start;
  double yy[C];
  for (int m = 0; m < C; ++m) {
    yy[m] = w[j + m];
    const double* v = l.x + l.p[j + m];
    for (int q = 1; q < C - m; ++q) w[j + m + q] -= v[q] * yy[m];
  }
  const int last = j + C - 1;
  const int* rows = l.i + l.p[last] + 1;
  const int count = l.nz[last] - 1;
  const double* v[C];
  for (int m = 0; m < C; ++m) v[m] = l.x + l.p[j + m] + (C - m);
  int k = 0;
  for (; k < count && rows[k] <= ch.limit; ++k) {
    double s = 0;
    for (int m = 0; m < C; ++m) s += v[m][k] * yy[m];
    w[rows[k]] -= s;
  }
  for (; k < count; ++k) {
    double s = 0;
    for (int m = 0; m < C; ++m) s += v[m][k] * yy[m];
    acc[rows[k]] -= s;
  }
}

// backward: w_j = w_j / D_j - L(:, j)' w over one chain, last column first
template <int C>
void backwardChain(const View& l, const LdlChain& ch, double* w) {
  const int j = ch.start;
  const int last = j + C - 1;
  const int* rows = l.i + l.p[last] + 1;
  const int count = l.nz[last] - 1;
  const double* v[C];
  for (int m = 0; m < C; ++m) v[m] = l.x + l.p[j + m] + (C - m);
  double dot[C] = {};
  for (int k = 0; k < count; ++k) {
    const double xr = w[rows[k]];
    for (int m = 0; m < C; ++m) dot[m] += v[m][k] * xr;
  }
  for (int m = C - 1; m >= 0; --m) {
    const double* col = l.x + l.p[j + m];
    double s = w[j + m] / col[0] - dot[m];
    for (int q = 1; q < C - m; ++q) s -= col[q] * w[j + m + q];
    w[j + m] = s;
  }
}

// the chain's kernel for its length (1 .. C)
template <int C>
void forwardAny(const View& l, const LdlChain& ch, double* w, double* acc) {
  if constexpr (C > 1)
    if (ch.count < C) return forwardAny<C - 1>(l, ch, w, acc);
  forwardChain<C>(l, ch, w, acc);
}

template <int C>
void backwardAny(const View& l, const LdlChain& ch, double* w) {
  if constexpr (C > 1)
    if (ch.count < C) return backwardAny<C - 1>(l, ch, w);
  backwardChain<C>(l, ch, w);
}

void forward(const View& l, const std::vector<LdlChain>& chains, double* w, double* acc) {
  for (const LdlChain& ch : chains) forwardAny<kMaxChain>(l, ch, w, acc);
}

void backward(const View& l, const std::vector<LdlChain>& chains, double* w) {
  for (auto it = chains.rbegin(); it != chains.rend(); ++it) backwardAny<kMaxChain>(l, *it, w);
}

}  // namespace

namespace {

// the plan for l's pattern: work.plan, made again when the pattern changed
LdlSolvePlan& planFor(const View& l, long minSplitEntries, LdlSolveWork& work) {
  const int n = l.n;
  if (!work.plan) work.plan = std::make_shared<LdlSolvePlan>();
  LdlSolvePlan& plan = *work.plan;
  bool same = plan.keyNz.size() == static_cast<size_t>(n) &&
              plan.minSplitEntries == minSplitEntries &&
              std::equal(plan.keyNz.begin(), plan.keyNz.end(), l.nz);
  for (int j = 0; same && j < n; ++j)
    same = plan.keyParent[j] == (l.nz[j] > 1 ? l.i[l.p[j] + 1] : -1);
  if (!same) {
    makePlan(l, minSplitEntries, plan);
    plan.minSplitEntries = minSplitEntries;
  }
  std::copy(std::begin(plan.work), std::end(plan.work), std::begin(work.work));
  return plan;
}

// w = D^-1 w, then w = L'^-1 w (the top first, then the two shares), and x = P' w
void backwardAndScatter(const View& l, const LdlSolvePlan& plan, int threads, LdlSolveWork& work,
                        double* x) {
  std::vector<double>& w = work.y;
  if (!plan.split) {
    backward(l, plan.chains[0], w.data());
  } else {
    backward(l, plan.chains[2], w.data());
    if (runTwoShares(threads, [&](int t) { backward(l, plan.chains[t], w.data()); }))
      work.threadsUsed = 2;
  }
  for (int k = 0; k < l.n; ++k) x[l.perm ? l.perm[k] : k] = w[k];
}

}  // namespace

void ldlSolve(const cholmod_factor& factor, const double* b, double* x, int threads,
              LdlSolveWork& work, long minSplitEntries) {
  const View l(factor);
  const int n = l.n;
  const LdlSolvePlan& plan = planFor(l, minSplitEntries, work);
  std::vector<double>& w = work.y;
  w.resize(n);
  for (int k = 0; k < n; ++k) w[k] = b[l.perm ? l.perm[k] : k];
  work.threadsUsed = 1;
  if (!plan.split) {
    forward(l, plan.chains[0], w.data(), nullptr);
  } else {
    for (auto& a : work.acc) a.resize(n, 0.0);  // only top rows are written, reset below
    if (runTwoShares(threads,
                     [&](int t) { forward(l, plan.chains[t], w.data(), work.acc[t].data()); }))
      work.threadsUsed = 2;
    for (int r : plan.topRows) {
      w[r] += work.acc[0][r] + work.acc[1][r];
      work.acc[0][r] = work.acc[1][r] = 0.0;
    }
    forward(l, plan.chains[2], w.data(), nullptr);
  }
  backwardAndScatter(l, plan, threads, work, x);
}

void ldlSolveBackward(const cholmod_factor& factor, const double* y, double* x, int threads,
                      LdlSolveWork& work, long minSplitEntries) {
  const View l(factor);
  const LdlSolvePlan& plan = planFor(l, minSplitEntries, work);
  work.y.assign(y, y + l.n);
  work.threadsUsed = 1;
  backwardAndScatter(l, plan, threads, work, x);
}

}  // namespace esim
