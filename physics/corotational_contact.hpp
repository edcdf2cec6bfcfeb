#pragma once
// Contacts inside the corotational quasi-static equilibrium (collision.coupling "solved").
//
// The frame's end u minimises the potential Pi(u) = E(u) - f . u (E the corotational elastic energy, whose gradient
// is f_int) subject to the contact rows H u >= g. Sequential quadratic programming with a fixed Hessian
// B = Rn K Rn^T: the rest stiffness turned by each node's rotation at the start (compliance warping, Saupin, Duriez
// and Cotin 2008). Each step solves
//   min 1/2 du^T B du - r^T du   subject to   H (u + du) >= g,   r = f - f_int(u) on the free DOFs,
// as an LCP on W = H B^-1 H^T = (H Rn) C (H Rn)^T, C the rest compliance's cached columns (SurfaceCompliance), and
// takes du = B^-1 (r + H^T lambda). From a feasible u, du = 0 is a feasible candidate, so r . du >= du^T B du / 2:
// du descends Pi; and since the rows are linear, every point between u and u + du is feasible. A backtracking line
// search on Pi therefore keeps each iterate feasible and lowers Pi at every step: the iteration cannot diverge.
// From an infeasible start (new rows) the line search is on the exact penalty Pi + mu sum max(0, g - H u) instead,
// mu twice the largest multiplier, along which du descends too (Han's merit function); a step that finds no
// decrease there is taken whole, which puts u on the rows.
// At the fixed point du = 0, i.e. r + H^T lambda = 0 with lambda >= 0 complementary to H u - g: the equilibrium of
// the corotational model itself with its contacts (the KKT conditions), which is what the residual measures.
#include <vector>

#include <Eigen/Core>

#include "physics/contact_rows.hpp"
#include "physics/corotational.hpp"
#include "physics/surface_compliance.hpp"

namespace lumen::physics {

// The fixed Hessian B of the QP steps, given as a factorised matrix with its compliance (SurfaceCompliance):
//   as_given        B itself (e.g. K_w at the rotations of the lagged factorisation that preconditions the solve,
//                   the stiffness-warping operator of the contact-free solves; Courtecuisse et al. 2010)
//   node_rotations  Rn B Rn^T, Rn each node's rotation at the start (on the rest K: compliance warping, Saupin et
//                   al. 2008, whose columns never change)
enum class ContactHessian { as_given, node_rotations };

// Bounds and tolerances of solve_contact_equilibrium (validated by it).
struct ContactEquilibriumOptions {
  ContactHessian hessian = ContactHessian::as_given;
  // Converged when |r + H^T lambda| on the free DOFs <= tolerance * force scale (the force scale: the largest of
  // |f| on the free DOFs, the support reactions and |H^T lambda|); > 0.
  double tolerance = 1e-3;
  int max_steps = 20;                  // QP steps (each: two back-substitutions, an LCP, a line search), >= 1
  // A start counts as on the rows when no row is violated by more than this, metres (> 0); the LCP's own
  // tolerance is a tenth of it.
  double feasibility_tolerance = 1e-6;
  // The LCP of each step: NNCG within this many sweeps, warm-started from the last multipliers, when > 0;
  // otherwise the active-set method warm-started from the pushing rows (Lemke's pivoting where it fails).
  int lcp_sweeps = 0;
  // A QP step is split (one forward and one backward sweep, the rows' nodes read and loaded through their half
  // columns; see WarpedQp) when the compliance is lazy, its solver's halves sweep its own factor
  // (StaticSolver::splits_on_its_factor), and the rows' nodes' half-column rows (three values each) number at most
  // this share of the factor's nonzeros; otherwise it takes two whole solves. A half-column row read costs about
  // eight of the factor's entries in a sweep (BM_PhysicsQpStepSolves: the split saves 45 % of the step's solves at
  // 20 row nodes, 25 % at 80 and 11 % at 150, 96k rows against the factor's 1.17 M nonzeros), so the break-even is
  // near 0.11. >= 0; 0: never split.
  double split_entry_share = 0.1;
};

// What solve_contact_equilibrium did.
struct ContactEquilibriumResult {
  int steps = 0;            // QP steps taken
  int backtracks = 0;       // line-search halvings over the steps
  int lcp_iterations = 0;   // pivots / rounds / sweeps over the LCPs
  int split_steps = 0;      // QP steps split (options.split_entry_share)
  bool lcp_converged = true;  // every LCP reached its tolerance
  double residual = 0.0;    // |r + H^T lambda| / force scale at the returned u (the KKT residual)
  bool converged = false;   // residual <= tolerance
  double violation = 0.0;   // largest g - H u over the rows at the returned u, metres (<= 0: none violated)
  int n_inverted = 0;       // tets with det F <= 0 at the returned u
  bool finite = true;       // false: the start's forces were not finite (nothing was done)
  Eigen::VectorXd lambda;   // per row, newtons: the multipliers of the last QP (at the returned u, or at the one
                            // before it when the step bound stopped the iteration)
  int refactor_failures = 0;  // Integrator::solve_with_contacts: factorisations of its Hessian that failed (the
                              // last one was kept)
};

// Runs the iteration above on state.u (in: the start, prescribed DOFs at their values; out: the last iterate, with
// state's cached evaluation at it). f: the loads (3n, newtons; fixed DOFs ignored). compliance: a SurfaceCompliance
// over the factorisation of B (symmetric positive definite on the model's free DOFs; the rest K or a lagged K_w).
// lambda_warm: per row, the multipliers to warm-start the first LCP (empty: none). The model's fixed DOFs must be
// whole nodes (they are: CorotationalModel fixes nodes). Throws std::invalid_argument for sizes or options out of
// range, or a compliance of another size.
ContactEquilibriumResult solve_contact_equilibrium(const CorotationalModel& model, const Eigen::VectorXd& f,
                                                   const std::vector<ContactRow>& rows, SurfaceCompliance& compliance,
                                                   const ContactEquilibriumOptions& options, CorotationalState& state,
                                                   const Eigen::VectorXd& lambda_warm = Eigen::VectorXd());

}  // namespace lumen::physics
