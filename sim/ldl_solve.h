// ldl_solve.h - A x = b with a simplicial LDL' factor of CHOLMOD (P A P' = L D L'), its two
// triangular solves split over two threads by the elimination tree (issue #11: the cut's
// structural solve is the longest stage of a frame at 8000 nodes, 13-15 ms of CHOLMOD's
// scalar cholmod_solve2, bound by memory bandwidth: one core reads ~14 GB/s here, two ~26).
//
// The split. Column j of L has its rows below the diagonal among j's ancestors in the
// elimination tree (parent(j) = L's first row below the diagonal), so two subtrees neither
// of which holds the other are independent in both solves. The plan takes subtrees off the
// top of the tree (largest first: the root's separator of a nested-dissection ordering,
// then the next level's) until the largest subtree left holds at most a tenth of the work
// left, and deals those subtrees to two threads, largest first to the lighter (work: entries
// of L). The columns taken off, the "top", are solved by one thread: after the subtrees in
// the forward solve (a subtree column's rows above its subtree's root are top rows: each
// thread adds into its own array there, summed after), before them in the backward solve
// (a subtree column reads top rows already solved). Runs of up to 8 columns that form a chain
// with the same pattern below (consecutive columns j, j + 1 where column j + 1's rows are
// column j's rows but j + 1: a node's three components, nodes of one separator; CHOLMOD's own
// solve takes up to 4) read their row indices and update (forward) or read (backward) their
// rows once: 1.5-1.9x faster on one thread than runs of 4 (README).
// The plan depends only on L's pattern (counts and first rows below the diagonal), and one
// thread runs the same plan (the two shares one after the other), so the result depends
// neither on the threads' timing nor on their number: the same bits every run, on any
// machine. It equals cholmod_solve2's to round-off (the top rows' sums are taken in another
// order). The plan is kept while L's pattern stays (checked each solve, O(n)).
#pragma once

#include <cholmod.h>

#include <memory>
#include <vector>

namespace esim {

struct LdlSolvePlan;

// what a solve keeps between calls (the plan, kept while L's pattern stays; workspaces sized
// to the factor on use) and what the last solve did
struct LdlSolveWork {
  std::shared_ptr<LdlSolvePlan> plan;
  std::vector<double> y, acc[2];  // the solve's vector; each share's sums into top rows (0
                                  // between solves)
  int threadsUsed = 0;            // last solve: 1 or 2
  long work[3] = {};              // the plan: entries of L in share 0, share 1, and the top
};

// can ldlSolve take this factor? (simplicial LDL', int indices, real double)
bool ldlSolveSupports(const cholmod_factor& l);

// x = A^-1 b (n entries each, b and x distinct) with the factor l of A, on 1 or 2 threads
// (the tree is split when L has at least minSplitEntries entries, else one thread solves it
// in one share). l must be supported (ldlSolveSupports).
void ldlSolve(const cholmod_factor& l, const double* b, double* x, int threads, LdlSolveWork& work,
              long minSplitEntries = 1000000);  // ~1 ms of one thread here

// x = P' L'^-1 D^-1 y: the second half of ldlSolve, for a y = L^-1 P b already known (y in L's
// row order, n entries; e.g. a sum of sparse forward solves, as electric_downdate.cpp's contact
// paths). The same plan and threads as ldlSolve; from the same y, the same bits as its x.
void ldlSolveBackward(const cholmod_factor& l, const double* y, double* x, int threads,
                      LdlSolveWork& work, long minSplitEntries = 1000000);

}  // namespace esim
