// A multiple-rank update or downdate of a simplicial LDL' factor, L D L' +- C C', vectorized
// over the rows of each column of L (issue #11: a removal's structural update is the
// cut's critical path, and CHOLMOD's cholmod_updown, as Debian builds it, is scalar code).
// The arithmetic is CHOLMOD's (Davis and Hager's multiple-rank method C1, the same
// alpha/gamma recurrence, up to 8 columns of C a pass, each pass along the union of its
// columns' paths in the elimination tree), so the results agree with cholmod_updown to
// rounding; it takes only the columns whose change stays inside L's pattern (no fill) and
// leaves the others to cholmod_updown.
#pragma once

#include <cholmod.h>

#include <Eigen/Core>
#include <functional>
#include <utility>
#include <vector>

namespace esim {

// Workspace kept across calls (sized to the factor on first use), and what the calls did.
struct LdlUpdownWork {
  std::vector<double> w;  // n x 8, row-major, zero between calls
  std::vector<int> mark;  // n, path marks
  std::vector<int> path;  // columns of the current pass's paths
  int stamp = 0;
  std::vector<int> cp, ci, restP, restI;  // the columns of C for the kernel, for CHOLMOD
  std::vector<double> cx, restX;
  std::vector<std::pair<int, int>> order;  // the kernel's columns: (first row, column of C)
  std::vector<std::vector<int>> paths;     // per pass of up to 8 columns: its columns of L
  std::vector<double> w2;                  // the second thread's W
  int threads = 1;                         // 2: passes pipelined on two threads (the same bits)
  bool pipelined = false;                  // the last call's passes ran on two threads
  long vectorColumns = 0;                  // columns of C the kernel applied
  long choleskyColumns = 0;                // ... and cholmod_updown (they would fill in L)
};

// The LDL' of a small dense symmetric matrix g (its lower triangle read and overwritten) as
// the columns of a multiple-rank change, pivoted in index order (the order of L's rows: a
// column is zero on the indices pivoted before it, so its path starts at the lowest index
// left): each pivot is the first index whose remaining diagonal is at least pivotShare of
// the largest remaining one, until that largest is at most 1e-12 of the largest diagonal at
// the start; the diagonals' sizes are their values (g semidefinite: one <= 0 is round-off)
// or, indefinite, their absolute values (a negative pivot: an update column). For each pivot, in
// order, column(d, c): d the pivot, c = g(:, p) on the indices not pivoted yet (0 on the others),
// so that g = sum c c' / d plus the rest. Returns the rest's largest |entry| over that starting
// largest (0 when nothing is left): round-off for a semidefinite g, more for an indefinite one
// whose diagonal ran out first. The structural phase's removed stiffness (semidefinite) and
// electric_downdate's change take their columns from it.
double pivotedLdl(Eigen::MatrixXd& g, double pivotShare, bool indefinite,
                  const std::function<void(double d, const Eigen::VectorXd& c)>& column);

// true when this machine runs the vectorized kernel (AVX-512F)
bool ldlUpdownAvailable();

// true when the column of C with these rows (ascending, in L's row order) would fill in the
// simplicial factor l: a row outside L's column at the first row (ldlUpdown leaves such a
// column to cholmod_updown)
bool ldlColumnFillsIn(const cholmod_factor& l, const int* rows, int count, LdlUpdownWork& work);

// L D L' + C C' (update) or - C C' (downdate), C n x r in L's row order (sorted columns,
// packed), as cholmod_updown(update, C, L) does: the columns whose change stays inside L's
// pattern by the kernel (in the order of their first rows: the result does not depend on the
// order of such columns with distinct first rows), the others (and all of them without
// AVX-512, or for a factor that is not simplicial LDL' with int indices) by cholmod_updown
// after it. Returns
// cholmod_updown's result (true when only the kernel ran). A downdate that loses positive
// definiteness leaves a pivot <= 0, as cholmod_updown does.
bool ldlUpdown(bool update, const cholmod_sparse& c, cholmod_factor& l, LdlUpdownWork& work,
               cholmod_common& cm);

// The columns j < k of L that may hold a nonzero in row k (its row subtree), appended to out in
// ascending order: the elimination tree climbed from each of `from` (the rows j where A(k, j)
// may be nonzero, L's row order; those not below k in the tree, or negative, are passed over)
// until k. A superset of the truth while L's pattern is the
// symbolic factor of A's (updates whose columns do not fill in, and ldlTakeRows, keep it).
void ldlRowSubtree(const cholmod_factor& l, int k, const int* from, int count, LdlUpdownWork& work,
                   std::vector<int>& out);

// Deletes rows of a simplicial LDL' factor of A: each becomes an identity row and column (what
// cholmod_rowdel makes of it) once the caller updates L by W W' (ldlUpdown), one multiple-rank
// update instead of a rank-1 pass up the elimination tree per row. With H the deleted rows and
// F the others, A_FF = L_FF D_F L_FF' + W W', W = L_FH D_H^(1/2) of the factor before, and L_FF
// is unit lower triangular: so W is taken out of L's columns H, the rows and columns H are
// cleared (D_H = 1), and W's columns lie in L's pattern (etree paths: nothing fills in).
// rows: ascending, in L's row order; rowSubtree(k, out) appends the columns j < k that may
// hold a nonzero in row k (ldlRowSubtree). W comes out in (wp, wi, wx): packed columns, rows
// ascending (an empty column left out). False, L unchanged, when a pivot of H is not positive.
bool ldlTakeRows(const std::vector<int>& rows,
                 const std::function<void(int, std::vector<int>&)>& rowSubtree, cholmod_factor& l,
                 std::vector<int>& wp, std::vector<int>& wi, std::vector<double>& wx);

}  // namespace esim
