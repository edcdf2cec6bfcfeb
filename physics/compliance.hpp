#pragma once
// Precomputed responses of a prefactorised FEM model (what makes a frame cheap) and contact solves on them:
// an umbrella over the five topic headers (include the one you need instead).
//
// Per-frame physics path: the loads of a frame act at a few fixed surface points (probe tips). LoadResponse
// precomputes U = K^-1 [unit forces at those points] once (one multi-column CHOLMOD solve); a frame is then
// u = U * forces, a dense 3n x 3m mat-vec (m = number of load points), no back-substitution at all.
//
// Contact path: SurfaceCompliance holds C = K^-1 restricted to a node set (the inner wall). Contacts are rows
// of a constraint matrix H; their coupling A = H C H^T is small and dense, so the multipliers lambda come from
// a dense solve (equality, the paper's "hold the colliding vertices") or an LCP (non-penetration: Lemke on all
// of A, or an active-set method that needs only the columns of A of its active rows, CouplingMatrix), and the
// whole-mesh correction du = K^-1 H^T lambda is a short sum of precomputed columns (few loaded nodes) or one
// back-substitution.
#include "physics/contact_rows.hpp"        // ContactRow, row_values, contact_force, CouplingMatrix, coupling_matrix
#include "physics/contact_solve.hpp"       // ContactResult, HeldPoints, solve_equality, solve_lcp, solve_contacts
#include "physics/lcp.hpp"                 // LcpOptions, LcpResult, solve_lcp_dense, solve_lcp_active_set
#include "physics/load_response.hpp"       // LoadPoint, LoadResponse
#include "physics/surface_compliance.hpp"  // SurfaceCompliance
