#pragma once
// The committed state's equilibrium with its contacts, measured from the state itself (the corotational
// quasi-static solve's elastic forces at the committed displacement): how far the frame's result is from a
// state the model could hold, and the contact force that state implies.
#include "engine/simulation.hpp"

namespace lumen::engine {

struct ContactEquilibrium {
  bool available = false;  // false: not a corotational quasi-static model (the other integrators are not measured)
  int rows = 0;            // active contact rows at the committed state
  // |f_int(u) - f_probes - H^T lambda| on the free DOFs over |f_probes|, with the committed multipliers
  // (State::active_total) ...
  double reported_residual = 0.0;
  // ... and with the non-negative multipliers that fit the state best (least squares over lambda >= 0).
  double fitted_residual = 0.0;
  double fitted_force = 0.0;  // newtons: the sum of the fitted multipliers (NaN when the fit did not converge)
};

// Measures the committed state: r = f_int(u) - f_probes on the free DOFs, G = H^T (one column per active
// contact row, re-linearised at the committed positions), the reported residual |r - G lambda| / |f_probes|,
// and the fit min |r - G lambda| over lambda >= 0: the LCP of G^T G and -G^T r, solved by Lemke's pivoting.
ContactEquilibrium contact_equilibrium(const Model& model, const State& state);

}  // namespace lumen::engine
