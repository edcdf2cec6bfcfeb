#pragma once
// Contact solves on a SurfaceCompliance: equality rows (the paper's "hold the colliding vertices"), and
// non-penetration as an LCP (Lemke on all of A, or the active-set method on columns of A computed on demand with
// Lemke as the fallback), optionally with load points held at their displacement.
#include <Eigen/Core>
#include <vector>

#include "physics/contact_rows.hpp"
#include "physics/lcp.hpp"
#include "physics/lcp_iterative.hpp"
#include "physics/load_response.hpp"
#include "physics/surface_compliance.hpp"

namespace lumen::physics {

// Result of a contact solve.
struct ContactResult {
  Eigen::VectorXd lambda;      // row multipliers, newtons, one per row (>= 0 for the LCP)
  Eigen::VectorXd force;       // f_c = H^T lambda, nodal contact forces, 3n, newtons
  Eigen::VectorXd correction;  // du = K^-1 f_c, 3n, metres: whole mesh, or (whole_mesh = false) only on the
                               // compliance's set and the rows' nodes (SurfaceCompliance::displacement_on_set)
  int iterations = 0;          // LCP pivots or active-set rounds (1 for the equality solve)
  double residual = 0.0;       // max row violation at u_free + du, metres (see solve_equality / solve_lcp)
  bool converged = false;      // residual <= tolerance
  bool used_lemke = false;     // solve_contacts: the active-set method failed and Lemke's pivoting was used
  Eigen::VectorXd held_force;  // solve_contacts with held points: change of their forces, 3d, newtons
};

// Load points held at prescribed displacements while contacts are solved (displacement-driven probes, grasps):
// their forces change so that the contacts do not move them. U: K^-1 of unit loads at the points (3n x 3d, m/N,
// e.g. columns of LoadResponse::response()), or empty (held_points_on): the solves then take G = H U from the
// compliance's 3 x 3 blocks and move the mesh by one displacement of the total force, with no 3d columns solved;
// S: the inverse of their point compliance (3d x 3d, N/m).
struct HeldPoints {
  std::vector<LoadPoint> points;  // d points
  Eigen::MatrixXd U;              // 3n x 3d, metres per newton (or empty)
  Eigen::MatrixXd S;              // 3d x 3d, newtons per metre
  bool has_columns() const { return U.size() > 0; }
};

// The points' compliance E^T K^-1 E (3d x 3d, m/N; E: unit loads at the points by their weights) from the
// compliance's 3 x 3 blocks: no solve for points on its set (the columns of other nodes are solved and cached).
Eigen::MatrixXd point_compliance(SurfaceCompliance& compliance, const std::vector<LoadPoint>& points);

// Held points without whole-mesh columns: S = (E^T K^-1 E)^-1 from point_compliance, U empty. The points' nodes
// must carry no fixed DOF (E^T K^-1 E is then symmetric positive definite).
HeldPoints held_points_on(SurfaceCompliance& compliance, std::vector<LoadPoint> points);

// Nodal forces E f (3n, newtons) of forces f at the points (3d, newtons, point order).
Eigen::VectorXd point_forces(const std::vector<LoadPoint>& points, const Eigen::VectorXd& f, int n_dofs);

// The whole-mesh displacement of forces f at the held points (3n, metres): U f with columns, else
// compliance.displacement(E f) (one back-substitution, or a short sum of kept columns). Both are K^-1 E f.
void held_displacement(SurfaceCompliance& compliance, const HeldPoints& held, const Eigen::VectorXd& f,
                       Eigen::VectorXd& du);

// Equality constraints H (u_free + du) = g: A lambda = g - H u_free (Cholesky, or the minimum-norm least-squares
// solution when A is singular; rows on fixed DOFs only, whose diagonal of A is 0, get lambda = 0 and do not
// spoil the Cholesky). residual = max |H u - g|; converged when <= tolerance (metres). whole_mesh = false: the
// correction only on the set and the rows' nodes (enough for the residual and for a check of the set).
ContactResult solve_equality(SurfaceCompliance& compliance, const std::vector<ContactRow>& rows,
                             const Eigen::VectorXd& u_free, double tolerance = 1e-9, bool whole_mesh = true);

// Non-penetration H u >= g with lambda >= 0 and lambda . (H u - g) = 0, by solve_lcp_dense on A.
// residual = max over rows of (g - H u)^+ and, where lambda > 0, |H u - g|.
ContactResult solve_lcp(SurfaceCompliance& compliance, const std::vector<ContactRow>& rows,
                        const Eigen::VectorXd& u_free, const LcpOptions& options = {});

// The same non-penetration problem by solve_lcp_active_set on columns of A computed on demand (a few per
// active row instead of all of A), warm-started from `warm` (row indices guessed to push, e.g. the rows of
// last frame's pushing contacts); when that does not converge, solve_lcp_dense on the whole A (used_lemke).
// whole_mesh as for solve_equality.
// With `held` (may be null), the held points keep their displacement: the LCP is on the Schur complement
// A - G S G^T (G = H U, rows x 3d), their force change is -S G^T lambda (held_force), and force and correction
// include it, so the points stay where they were in u_free (exactly, up to round-off).
ContactResult solve_contacts(SurfaceCompliance& compliance, const std::vector<ContactRow>& rows,
                             const Eigen::VectorXd& u_free, const std::vector<int>& warm = {},
                             const LcpOptions& options = {}, bool whole_mesh = true,
                             const HeldPoints* held = nullptr);

// The same non-penetration problem for many contacts: NNCG (solve_lcp_nncg) on all of A' (every column
// computed), warm-started from options.warm (per-row multipliers, e.g. last frame's), within options.max_sweeps.
// iterations = sweeps spent; residual as for solve_contacts; converged = residual <= options.tolerance. Running
// out of sweeps is not an error (converged = false, the residual reached is reported). whole_mesh and held as
// for solve_contacts.
ContactResult solve_contacts_iterative(SurfaceCompliance& compliance, const std::vector<ContactRow>& rows,
                                       const Eigen::VectorXd& u_free, const IterativeLcpOptions& options,
                                       bool whole_mesh = true, const HeldPoints* held = nullptr);

}  // namespace lumen::physics
