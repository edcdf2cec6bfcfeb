// Corotational tet kernels (rotations, forces, warped products), PCG on the warped system, quasi-static solve.
#include "physics/corotational.hpp"
#include "physics/detail/messages.hpp"

#include "physics/detail/dofs.hpp"
#include "physics/detail/element_lanes.hpp"

#include <Eigen/Dense>
#include <Eigen/IterativeLinearSolvers>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

#include <sys/resource.h>  // setpriority (the background factorisation's thread)
#include <unistd.h>        // gettid

namespace lumen::physics {

namespace {

// The fewest back-substitutions a PCG step takes (the start's preconditioning and one iteration's): a work bound
// with fewer left ends the solve.
constexpr int kPcgStepBackSubstitutions = 2;
// After the secant start was refused (it did not lower the residual: one evaluation of the rotations and forces
// for nothing), this many solves start where the last one ended before it is tried again.
constexpr int kSecantRetryAfter = 4;
// The twist modes' index pairs (i, j) of the signed singular values, and the least s_i + s_j at which a twist
// eigenvalue (psi_i + psi_j) / (s_i + s_j) is evaluated (below it the tet has collapsed across the pair).
constexpr int kTwistPairs[3][2] = {{1, 2}, {0, 2}, {0, 1}};
constexpr double kMinTwistStretch = 1e-6;
// Newton steps' backtracking line search: at most this many halvings, and Armijo's sufficient-decrease fraction.
constexpr int kMaxBacktracks = 4;
constexpr double kArmijo = 1e-4;
// A solve whose residual |r| (newtons) grows past this multiple of its start, or stops being finite, is diverging
// (a lagged factorisation far from the current tangent): it goes back to its start. Converging solves do go up
// before they come down: measured largest |r| / start 23 over the physics tests (the first linear step of a
// cantilever from rest) and 36-230 in three chord runs of the 0.08 N press (snap-through frames); a diverging one
// grows geometrically (it reached 1e300 m in one measured run). The relative residual cannot tell, since |f_int|
// grows with it. (The iterates past the start are never collided or committed, so a generous bound costs only
// steps.)
constexpr double kDivergenceGrowth = 1e4;
// Nice value of the background factorisation's thread (Linux: per thread). A session has up to three busy threads on
// two cores (the frame's, the frame writer's and this one); the frame's must not be the one that waits, and a
// factorisation landing a frame later only lags the preconditioner.
constexpr int kBackgroundFactorisationNice = 19;

// Tets [t0, t0 + m) into the lanes, m = min(kElementLanes, n_tets - t0) returned: rotations (unless R is null), the
// edges of v (3n: v_{a+1} - v_0 as column a), Dm^-1 and volumes; the lanes past m get identities and no volume (no
// force, no energy).
int fill_lanes(const Tets& tets, const std::vector<Eigen::Matrix3d>& grad, const std::vector<double>& volume,
               const std::vector<Eigen::Matrix3d>* R, const Eigen::VectorXd& v, int t0, detail::ElementLanes& e) {
  const int m = std::min(detail::kElementLanes, static_cast<int>(tets.rows()) - t0);
  for (int l = 0; l < detail::kElementLanes; ++l) {
    if (l >= m) {
      for (int c = 0; c < 9; ++c) {
        e.R[c][l] = e.G[c][l] = c % 4 == 0 ? 1.0 : 0.0;  // (entries 0, 4, 8: the diagonal)
        e.D[c][l] = 0.0;
      }
      e.V[l] = 0.0;
      continue;
    }
    const int t = t0 + l;
    const double* x0 = v.data() + 3 * tets(t, 0);
    for (int a = 0; a < 3; ++a) {
      const double* xa = v.data() + 3 * tets(t, a + 1);
      for (int k = 0; k < 3; ++k) e.D[3 * a + k][l] = xa[k] - x0[k];
    }
    for (int c = 0; c < 9; ++c) {
      if (R) e.R[c][l] = (*R)[t].data()[c];
      e.G[c][l] = grad[t].data()[c];
    }
    e.V[l] = volume[t];
  }
  return m;
}

// The lanes' element forces added to out (3n): P's column a on node a+1, minus their sum on node 0.
void scatter_lanes(const Tets& tets, const detail::ElementLanes& e, int t0, int m, Eigen::VectorXd& out) {
  for (int l = 0; l < m; ++l) {
    const int t = t0 + l;
    double* f0 = out.data() + 3 * tets(t, 0);
    for (int a = 0; a < 3; ++a) {
      double* fa = out.data() + 3 * tets(t, a + 1);
      for (int k = 0; k < 3; ++k) {
        fa[k] += e.P[3 * a + k][l];
        f0[k] -= e.P[3 * a + k][l];
      }
    }
  }
}

}  // namespace

// ---------------------------------------------------------------------------------------------------------------
// CorotationalElements

CorotationalElements::CorotationalElements(const TetMesh& mesh, const LinearMaterial& material,
                                           const Eigen::VectorXd& support)
    : n_nodes_(mesh.n_nodes()), tets_(mesh.tets), material_(material) {
  set_support(support);
  const LameParameters lame = lame_parameters(material);  // validates the material
  lambda_ = lame.lambda;
  mu_ = lame.mu;
  const int nt = n_tets();
  grad_.resize(nt);
  volume_.resize(nt);
  // Rest edge matrix Dm (columns X_a - X_0), volume det(Dm) / 6 and gradients Dm^-1 per tet.
  for (int t = 0; t < nt; ++t) {
    for (int a = 0; a < 4; ++a) {
      const int v = tets_(t, a);
      if (v < 0 || v >= n_nodes_) {
        detail::fail_must("CorotationalElements", "mesh.tets(" + std::to_string(t) + ", " + std::to_string(a) + ")",
             ("be a node id in [0, " + std::to_string(n_nodes_) + ")").c_str(), v);
      }
    }
    Eigen::Matrix3d Dm;
    for (int a = 0; a < 3; ++a) Dm.col(a) = (mesh.rest.row(tets_(t, a + 1)) - mesh.rest.row(tets_(t, 0))).transpose();
    volume_[t] = Dm.determinant() / 6.0;
    if (!(volume_[t] > 0.0) || !std::isfinite(volume_[t])) {
      detail::fail_must("CorotationalElements", "rest volume of tet " + std::to_string(t), "be > 0 and finite", volume_[t]);
    }
    grad_[t] = Dm.inverse();
  }
  build_node_elements();
}

CorotationalElements::CorotationalElements(const QuadraticMesh& mesh, const LinearMaterial& material,
                                           const Eigen::VectorXd& support)
    : n_nodes_(mesh.n_nodes()), order_(ElementOrder::kQuadratic), material_(material) {
  set_support(support);
  const LameParameters lame = lame_parameters(material);  // validates the material
  lambda_ = lame.lambda;
  mu_ = lame.mu;
  nodes10_ = mesh.tets;
  tets_ = mesh.tets.leftCols<4>();
  rest10_ = mesh.rest;
  const int nt = n_tets();
  volume_.resize(nt);
  mean_grad10_.resize(nt);
  stiffness10_.resize(static_cast<size_t>(nt) * kTet10Dofs * kTet10Dofs);
  // Per element: its rest nodes, volume, averaged gradients and stiffness (Jacobians checked by quadratic.cpp).
  for (int t = 0; t < nt; ++t) {
    Eigen::Matrix<double, 10, 3> X;
    for (int a = 0; a < 10; ++a) {
      const int v = nodes10_(t, a);
      if (v < 0 || v >= n_nodes_) {
        detail::fail_must("CorotationalElements", "mesh.tets(" + std::to_string(t) + ", " + std::to_string(a) + ")",
                          ("be a node id in [0, " + std::to_string(n_nodes_) + ")").c_str(), v);
      }
      X.row(a) = mesh.rest.row(v);
    }
    volume_[t] = tet10_volume(X);
    mean_grad10_[t] = tet10_mean_gradients(X);
    Eigen::Map<Eigen::Matrix<double, 30, 30>>(stiffness10_.data() + kTet10Dofs * kTet10Dofs * t) =
        tet10_stiffness(X, material);
  }
  build_node_elements();
}

void CorotationalElements::build_node_elements() {
  const int nt = n_tets();
  const int per_element = order_ == ElementOrder::kLinear ? 4 : 10;
  // The stiffness matrices' pattern and where each element's entries go in it.
  assembly_ = order_ == ElementOrder::kLinear ? ElementAssembly(tets_.data(), nt, 4, n_nodes_)
                                             : ElementAssembly(nodes10_.data(), nt, 10, n_nodes_);
  // Node -> incident elements (CSR, over every node of an element), for per-node rotations.
  auto node = [&](int t, int a) { return order_ == ElementOrder::kLinear ? tets_(t, a) : nodes10_(t, a); };
  node_tet_start_.assign(n_nodes_ + 1, 0);
  for (int t = 0; t < nt; ++t)
    for (int a = 0; a < per_element; ++a) ++node_tet_start_[node(t, a) + 1];
  for (int v = 0; v < n_nodes_; ++v) node_tet_start_[v + 1] += node_tet_start_[v];
  node_tet_.resize(node_tet_start_[n_nodes_]);
  std::vector<int> fill(node_tet_start_.begin(), node_tet_start_.end() - 1);
  for (int t = 0; t < nt; ++t)
    for (int a = 0; a < per_element; ++a) node_tet_[fill[node(t, a)]++] = t;
}

void CorotationalElements::set_support(const Eigen::VectorXd& support) {
  if (support.size() == 0) return;
  detail::check_vector("CorotationalElements", "support", support, n_dofs());
  for (Eigen::Index d = 0; d < support.size(); ++d)
    if (!(support[d] >= 0.0))
      detail::fail_must("CorotationalElements", "support[" + std::to_string(d) + "]", "be >= 0", support[d]);
  support_ = support;
}

void CorotationalElements::add_support(const Eigen::VectorXd& v, Eigen::VectorXd& y) const {
  if (support_.size()) y.array() += support_.array() * v.array();
}

double CorotationalElements::support_energy(const Eigen::VectorXd& u) const {
  return support_.size() ? 0.5 * support_.dot(u.cwiseProduct(u)) : 0.0;
}

Eigen::SparseMatrix<double> CorotationalElements::with_support(Eigen::SparseMatrix<double> K) const {
  if (!support_.size()) return K;
  // (In place: a diagonal entry missing from K's pattern is inserted.)
  for (int d = 0; d < n_dofs(); ++d)
    if (support_[d] != 0.0) K.coeffRef(d, d) += support_[d];
  K.makeCompressed();
  return K;
}

void CorotationalElements::require_linear(const char* where) const {
  if (order_ != ElementOrder::kLinear)
    throw std::invalid_argument(std::string(where) + ": needs 4-node tets (the 10-node corotational element has no "
                                                     "twist modes: warped steps only)");
}

Eigen::Matrix3d CorotationalElements::deformation_gradient(const Eigen::VectorXd& u, int t) const {
  const char* where = "CorotationalElements::deformation_gradient";
  if (u.size() != n_dofs()) detail::fail_must(where, "u.size()", ("be 3n = " + std::to_string(n_dofs())).c_str(), u.size());
  if (t < 0 || t >= n_tets()) detail::fail_must(where, "t", ("be in [0, " + std::to_string(n_tets()) + ")").c_str(), t);
  return gradient(u, t);
}

Eigen::Matrix3d CorotationalElements::gradient(const Eigen::VectorXd& u, int t) const {
  // 10-node tets: the volume average F = I + sum_a u_a (x) G_a.
  if (order_ == ElementOrder::kQuadratic) {
    Eigen::Matrix3d F = Eigen::Matrix3d::Identity();
    for (int a = 0; a < 10; ++a) F += u.segment<3>(3 * nodes10_(t, a)) * mean_grad10_[t].row(a);
    return F;
  }
  // F = I + Du Dm^-1 with Du the displacement edges u_a - u_0 as columns.
  const Eigen::Vector3d u0 = u.segment<3>(3 * tets_(t, 0));
  Eigen::Matrix3d Du;
  for (int a = 0; a < 3; ++a) Du.col(a) = u.segment<3>(3 * tets_(t, a + 1)) - u0;
  return Eigen::Matrix3d::Identity() + Du * grad_[t];
}

int CorotationalElements::rotations(const Eigen::VectorXd& u, std::vector<Eigen::Matrix3d>& R) const {
  detail::check_vector("CorotationalElements::rotations", "u", u, n_dofs());
  R.resize(n_tets());
  return proper_rotations(n_tets(), [&](int t) { return gradient(u, t); }, R.data());
}

void CorotationalElements::elastic_forces(const Eigen::VectorXd& u, const std::vector<Eigen::Matrix3d>& R,
                                          Eigen::VectorXd& f, double* energy) const {
  check_rotations("CorotationalElements::elastic_forces", R);
  if (u.size() != n_dofs()) detail::fail_must("CorotationalElements::elastic_forces", "u.size()", "be 3n", u.size());
  double elements = 0.0;
  if (order_ == ElementOrder::kQuadratic) {
    elements = quadratic_forces(u, R, f);
  } else {
    // Strain of the unrotated element, eps = sym(R^T F) - I, its stress, the nodal forces V R sigma grad N_a, and
    // its energy V eps : sigma / 2, a batch of tets at a time.
    f.setZero(n_dofs());
    detail::ElementLanes lanes;
    alignas(32) double F[9][detail::kElementLanes];
    for (int t0 = 0; t0 < n_tets(); t0 += detail::kElementLanes) {
      const int m = fill_lanes(tets_, grad_, volume_, &R, u, t0, lanes);
      detail::gradient_lanes(lanes, true, F);
      detail::element_stress_lanes(lanes, F, lambda_, mu_, true);
      for (int l = 0; l < m; ++l) elements += lanes.energy[l];
      scatter_lanes(tets_, lanes, t0, m, f);
    }
  }
  add_support(u, f);
  if (energy) *energy = elements + support_energy(u);
}

int CorotationalElements::rotations_and_forces(const Eigen::VectorXd& u, std::vector<Eigen::Matrix3d>& R,
                                               Eigen::VectorXd& f, double* energy) const {
  if (order_ == ElementOrder::kQuadratic) {
    const int inverted = rotations(u, R);
    elastic_forces(u, R, f, energy);
    return inverted;
  }
  detail::check_vector("CorotationalElements::rotations_and_forces", "u", u, n_dofs());
  static_assert(detail::kElementLanes == detail::kPolarLanes, "one batch for the rotations and the forces");
  R.resize(n_tets());
  f.setZero(n_dofs());
  double elements = 0.0;
  int inverted = 0;
  detail::ElementLanes lanes;
  alignas(32) double F[9][detail::kPolarLanes], X[9][detail::kPolarLanes];  // X: F, iterated to its rotation
  for (int t0 = 0; t0 < n_tets(); t0 += detail::kElementLanes) {
    // A batch's nodes read once: its deformation gradients (computed once), their rotations (into R and the lanes),
    // the stresses, forces and energies, scattered.
    const int m = fill_lanes(tets_, grad_, volume_, nullptr, u, t0, lanes);
    detail::gradient_lanes(lanes, true, F);
    std::copy(&F[0][0], &F[0][0] + 9 * detail::kPolarLanes, &X[0][0]);
    inverted += rotations_of_lanes(X, t0, m, [&](int t) { return gradient(u, t); }, R.data());
    for (int l = 0; l < detail::kElementLanes; ++l)
      for (int c = 0; c < 9; ++c) lanes.R[c][l] = l < m ? R[t0 + l].data()[c] : (c % 4 == 0 ? 1.0 : 0.0);
    detail::element_stress_lanes(lanes, F, lambda_, mu_, true);
    for (int l = 0; l < m; ++l) elements += lanes.energy[l];
    scatter_lanes(tets_, lanes, t0, m, f);
  }
  add_support(u, f);
  if (energy) *energy = elements + support_energy(u);
  return inverted;
}

void CorotationalElements::warped_product(const std::vector<Eigen::Matrix3d>& R, const Eigen::VectorXd& p,
                                          Eigen::VectorXd& y) const {
  check_rotations("CorotationalElements::warped_product", R);
  if (p.size() != n_dofs()) detail::fail_must("CorotationalElements::warped_product", "p.size()", "be 3n", p.size());
  if (order_ == ElementOrder::kQuadratic) {
    quadratic_product(R, p, y);
    return add_support(p, y);
  }
  // R K_e R^T p_e: strain of the unrotated displacement gradient R^T (Dp Dm^-1), stress, rotated nodal forces, a
  // batch of tets at a time.
  y.setZero(n_dofs());
  detail::ElementLanes lanes;
  alignas(32) double H[9][detail::kElementLanes];
  for (int t0 = 0; t0 < n_tets(); t0 += detail::kElementLanes) {
    const int m = fill_lanes(tets_, grad_, volume_, &R, p, t0, lanes);
    detail::gradient_lanes(lanes, false, H);
    detail::element_stress_lanes(lanes, H, lambda_, mu_, false);
    scatter_lanes(tets_, lanes, t0, m, y);
  }
  add_support(p, y);
}

void CorotationalElements::check_rotations(const char* where, const std::vector<Eigen::Matrix3d>& R) const {
  if (static_cast<int>(R.size()) != n_tets())
    detail::fail_must(where, "R.size()", ("be n_tets = " + std::to_string(n_tets())).c_str(), R.size());
}

void CorotationalElements::check_modes(const char* where, const std::vector<TwistModes>& modes) const {
  if (static_cast<int>(modes.size()) != n_tets())
    detail::fail_must(where, "modes.size()", ("be n_tets = " + std::to_string(n_tets())).c_str(), modes.size());
}

void CorotationalElements::shape_gradients(int t, Eigen::Vector3d (&g)[4]) const {
  for (int a = 0; a < 3; ++a) g[a + 1] = grad_[t].row(a).transpose();
  g[0] = -(g[1] + g[2] + g[3]);
}

Eigen::Matrix<double, 12, 12> CorotationalElements::warped_element(const Eigen::Matrix3d& R, int t) const {
  // Shape-function gradients g_a (g_0 = -(g_1 + g_2 + g_3)), 1/metres.
  Eigen::Vector3d g[4];
  shape_gradients(t, g);
  // Block (a, b) of K_e is V (lambda g_a g_b^T + mu g_b g_a^T + mu (g_a . g_b) I); warped: R K_ab R^T.
  Eigen::Matrix<double, 12, 12> W;
  for (int a = 0; a < 4; ++a)
    for (int b = 0; b < 4; ++b) {
      Eigen::Matrix3d Kab = lambda_ * g[a] * g[b].transpose() + mu_ * g[b] * g[a].transpose();
      Kab.diagonal().array() += mu_ * g[a].dot(g[b]);
      W.block<3, 3>(3 * a, 3 * b) = volume_[t] * (R * Kab * R.transpose());  // (as a 3 x 3: same round-off)
    }
  return W;
}

Eigen::SparseMatrix<double> CorotationalElements::warped_stiffness(const std::vector<Eigen::Matrix3d>& R) const {
  check_rotations("CorotationalElements::warped_stiffness", R);
  if (order_ == ElementOrder::kQuadratic) return with_support(quadratic_stiffness(R));
  Eigen::SparseMatrix<double> K = assembly_.zero_matrix();
  for (int t = 0; t < n_tets(); ++t) assembly_.add(t, warped_element(R[t], t), K);
  return with_support(std::move(K));
}

void CorotationalElements::twist_modes(const Eigen::VectorXd& u, const std::vector<Eigen::Matrix3d>& R,
                                       bool project, std::vector<TwistModes>& modes) const {
  require_linear("CorotationalElements::twist_modes");
  check_rotations("CorotationalElements::twist_modes", R);
  detail::check_vector("CorotationalElements::twist_modes", "u", u, n_dofs());
  modes.resize(n_tets());
  for (int t = 0; t < n_tets(); ++t) {
    // Signed singular values s and frame Q of the symmetric stretch R^T F = Q diag(s) Q^T; U = R Q.
    Eigen::Matrix3d S = R[t].transpose() * gradient(u, t);
    S = (0.5 * (S + S.transpose())).eval();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen;
    eigen.computeDirect(S);
    const Eigen::Vector3d& s = eigen.eigenvalues();
    const Eigen::Matrix3d& Q = eigen.eigenvectors();
    const Eigen::Matrix3d U = R[t] * Q;
    // dpsi/ds_i of psi = mu sum (s_i - 1)^2 + lambda/2 (sum s_i - 3)^2.
    const Eigen::Vector3d dpsi = (2.0 * mu_ * (s.array() - 1.0) + lambda_ * (s.sum() - 3.0)).matrix();
    // Shape-function gradients g_a (g_0 = -(g_1 + g_2 + g_3)), 1/metres.
    Eigen::Vector3d g[4];
    shape_gradients(t, g);
    // Per twist mode: its eigenvalue (clamped when projecting; left out where the tet has collapsed across the
    // pair, s_i + s_j <= 0, and the mode is undefined) and the nodal gradient of dF : T_k.
    TwistModes& m = modes[t];
    for (int k = 0; k < 3; ++k) {
      const int i = kTwistPairs[k][0], j = kTwistPairs[k][1];
      const Eigen::Matrix3d T = (U.col(i) * Q.col(j).transpose() - U.col(j) * Q.col(i).transpose()) / std::sqrt(2.0);
      const double sum = s[i] + s[j];
      double eigenvalue = sum > kMinTwistStretch ? (dpsi[i] + dpsi[j]) / sum : 0.0;
      if (project) eigenvalue = std::max(0.0, eigenvalue);
      m.stiffness[k] = volume_[t] * eigenvalue;
      for (int a = 0; a < 4; ++a) m.b.block<3, 1>(3 * a, k) = T * g[a];
    }
  }
}

void CorotationalElements::tangent_product(const std::vector<Eigen::Matrix3d>& R, const std::vector<TwistModes>& modes,
                                           const Eigen::VectorXd& p, Eigen::VectorXd& y) const {
  require_linear("CorotationalElements::tangent_product");
  check_modes("CorotationalElements::tangent_product", modes);
  warped_product(R, p, y);
  for (int t = 0; t < n_tets(); ++t) {
    // y_e += b diag(stiffness) b^T p_e.
    Eigen::Matrix<double, 12, 1> pe;
    for (int a = 0; a < 4; ++a) pe.segment<3>(3 * a) = p.segment<3>(3 * tets_(t, a));
    const Eigen::Vector3d c = (modes[t].b.transpose() * pe).cwiseProduct(modes[t].stiffness);
    const Eigen::Matrix<double, 12, 1> ye = modes[t].b * c;
    for (int a = 0; a < 4; ++a) y.segment<3>(3 * tets_(t, a)) += ye.segment<3>(3 * a);
  }
}

Eigen::SparseMatrix<double> CorotationalElements::tangent_stiffness(const std::vector<Eigen::Matrix3d>& R,
                                                                    const std::vector<TwistModes>& modes) const {
  require_linear("CorotationalElements::tangent_stiffness");
  check_rotations("CorotationalElements::tangent_stiffness", R);
  check_modes("CorotationalElements::tangent_stiffness", modes);
  Eigen::SparseMatrix<double> K = assembly_.zero_matrix();
  for (int t = 0; t < n_tets(); ++t) {
    const Eigen::Matrix<double, 12, 12> Kt =
        warped_element(R[t], t) + modes[t].b * modes[t].stiffness.asDiagonal() * modes[t].b.transpose();
    assembly_.add(t, Kt, K);
  }
  return with_support(std::move(K));
}

double CorotationalElements::elastic_energy(const Eigen::VectorXd& u, const std::vector<Eigen::Matrix3d>& R) const {
  check_rotations("CorotationalElements::elastic_energy", R);
  detail::check_vector("CorotationalElements::elastic_energy", "u", u, n_dofs());
  const double springs = support_energy(u);
  if (order_ == ElementOrder::kQuadratic) return quadratic_energy(u, R) + springs;
  double energy = springs;
  for (int t = 0; t < n_tets(); ++t) {
    // V (mu eps:eps + lambda/2 tr(eps)^2) with the unrotated strain.
    const Eigen::Matrix3d S = R[t].transpose() * gradient(u, t);
    Eigen::Matrix3d eps = 0.5 * (S + S.transpose());
    eps.diagonal().array() -= 1.0;
    const double tr = eps.trace();
    energy += volume_[t] * (mu_ * eps.squaredNorm() + 0.5 * lambda_ * tr * tr);
  }
  return energy;
}

void CorotationalElements::node_rotations(const std::vector<Eigen::Matrix3d>& R,
                                          std::vector<Eigen::Matrix3d>& node_R) const {
  check_rotations("CorotationalElements::node_rotations", R);
  node_R.resize(n_nodes_);
  // Rotation nearest to the sum of the incident tets' rotations (a node in no tet: identity).
  proper_rotations(
      n_nodes_,
      [&](int v) {
        if (node_tet_start_[v + 1] == node_tet_start_[v]) return Eigen::Matrix3d(Eigen::Matrix3d::Identity());
        Eigen::Matrix3d sum = Eigen::Matrix3d::Zero();
        for (int k = node_tet_start_[v]; k < node_tet_start_[v + 1]; ++k) sum += R[node_tet_[k]];
        return sum;
      },
      node_R.data());
}

// 10-node kernels: the element's displacement unrotated by R^T, times the stored K_e, rotated back by R.

Eigen::Matrix<double, 30, 1> CorotationalElements::unrotated_displacement(const Eigen::VectorXd& u,
                                                                          const Eigen::Matrix3d& R, int t) const {
  // Relative to the element's first node (K_e has translations in its null space), so that positions far from
  // the origin do not swamp small displacements in round-off.
  const int v0 = nodes10_(t, 0);
  const Eigen::Vector3d X0 = rest10_.row(v0).transpose(), u0 = u.segment<3>(3 * v0);
  Eigen::Matrix<double, 30, 1> d;
  for (int a = 0; a < 10; ++a) {
    const int v = nodes10_(t, a);
    const Eigen::Vector3d dX = rest10_.row(v).transpose() - X0;
    d.segment<3>(3 * a) = R.transpose() * (dX + u.segment<3>(3 * v) - u0) - dX;
  }
  return d;
}

double CorotationalElements::quadratic_forces(const Eigen::VectorXd& u, const std::vector<Eigen::Matrix3d>& R,
                                              Eigen::VectorXd& f) const {
  f.setZero(n_dofs());
  double energy = 0.0;
  for (int t = 0; t < n_tets(); ++t) {
    // f_e = R K_e d with d = R^T x_e - X_e, and the energy d^T K_e d / 2.
    const Eigen::Matrix<double, 30, 1> d = unrotated_displacement(u, R[t], t);
    const Eigen::Matrix<double, 30, 1> fe = element_stiffness(t) * d;
    energy += 0.5 * d.dot(fe);
    for (int a = 0; a < 10; ++a) f.segment<3>(3 * nodes10_(t, a)) += R[t] * fe.segment<3>(3 * a);
  }
  return energy;
}

void CorotationalElements::quadratic_product(const std::vector<Eigen::Matrix3d>& R, const Eigen::VectorXd& p,
                                             Eigen::VectorXd& y) const {
  y.setZero(n_dofs());
  for (int t = 0; t < n_tets(); ++t) {
    // y_e = R K_e R^T p_e.
    Eigen::Matrix<double, 30, 1> pe;
    for (int a = 0; a < 10; ++a) pe.segment<3>(3 * a) = R[t].transpose() * p.segment<3>(3 * nodes10_(t, a));
    const Eigen::Matrix<double, 30, 1> ye = element_stiffness(t) * pe;
    for (int a = 0; a < 10; ++a) y.segment<3>(3 * nodes10_(t, a)) += R[t] * ye.segment<3>(3 * a);
  }
}

Eigen::SparseMatrix<double> CorotationalElements::quadratic_stiffness(const std::vector<Eigen::Matrix3d>& R) const {
  Eigen::SparseMatrix<double> K = assembly_.zero_matrix();
  Eigen::Matrix<double, 30, 30> W;
  for (int t = 0; t < n_tets(); ++t) {
    // Block (a, b): R K_ab R^T.
    const auto Ke = element_stiffness(t);
    for (int a = 0; a < 10; ++a)
      for (int b = 0; b < 10; ++b)
        W.block<3, 3>(3 * a, 3 * b) = R[t] * Ke.block<3, 3>(3 * a, 3 * b) * R[t].transpose();
    assembly_.add(t, W, K);
  }
  return K;
}

double CorotationalElements::quadratic_energy(const Eigen::VectorXd& u, const std::vector<Eigen::Matrix3d>& R) const {
  double energy = 0.0;
  for (int t = 0; t < n_tets(); ++t) {
    // 1/2 d^T K_e d with d the unrotated displacement.
    const Eigen::Matrix<double, 30, 1> d = unrotated_displacement(u, R[t], t);
    energy += 0.5 * d.dot(element_stiffness(t) * d);
  }
  return energy;
}

// ---------------------------------------------------------------------------------------------------------------
// PCG on the warped system with Eigen's ConjugateGradient: a matrix-free operator and a CHOLMOD preconditioner.

namespace {
class WarpedOperator;
}  // namespace
}  // namespace lumen::physics

// The operator has the traits of a sparse matrix, as in Eigen's matrix-free solver example.
template <>
struct Eigen::internal::traits<lumen::physics::WarpedOperator> : public traits<Eigen::SparseMatrix<double>> {};

namespace lumen::physics {
namespace {

// y = A p = c_mass M p + c_stiffness K_w p, zero on the fixed DOFs (Eigen matrix-free operator).
class WarpedOperator : public Eigen::EigenBase<WarpedOperator> {
 public:
  using Scalar = double;
  using RealScalar = double;
  using StorageIndex = int;
  enum { ColsAtCompileTime = Eigen::Dynamic, MaxColsAtCompileTime = Eigen::Dynamic, IsRowMajor = false };

  WarpedOperator(const WarpedSystem& system, const std::vector<char>& fixed) : system_(system), fixed_(fixed) {}
  Eigen::Index rows() const { return system_.elements->n_dofs(); }
  Eigen::Index cols() const { return system_.elements->n_dofs(); }

  template <typename Rhs>
  Eigen::Product<WarpedOperator, Rhs, Eigen::AliasFreeProduct> operator*(const Eigen::MatrixBase<Rhs>& x) const {
    return Eigen::Product<WarpedOperator, Rhs, Eigen::AliasFreeProduct>(*this, x.derived());
  }

  // y = A p (p is zero on the fixed DOFs); a zero p (CG's initial residual with a zero guess) costs nothing.
  void apply(const Eigen::VectorXd& p, Eigen::VectorXd& y) const {
    if (p.isZero(0.0)) {
      y.setZero(p.size());
      return;
    }
    if (system_.twist)
      system_.elements->tangent_product(*system_.rotations, *system_.twist, p, y);
    else
      system_.elements->warped_product(*system_.rotations, p, y);
    y *= system_.c_stiffness;
    if (system_.c_mass != 0.0) y.array() += system_.c_mass * system_.mass->array() * p.array();
    if (system_.contacts) add_contact_stiffness(p, y);
    for (Eigen::Index i = 0; i < y.size(); ++i)
      if (fixed_[i]) y[i] = 0.0;
  }

 private:
  // y += stiffness h_r (h_r . p) for every pushing contact row (row_values and contact_force compute the same but
  // check the rows on every call; this is the CG operator, and the rows were checked once by the solve).
  void add_contact_stiffness(const Eigen::VectorXd& p, Eigen::VectorXd& y) const {
    const AugmentedContacts& c = *system_.contacts;
    for (size_t r = 0; r < c.rows.size(); ++r) {
      if (!(*system_.pushing)[r]) continue;
      const ContactRow& row = c.rows[r];
      double hp = 0.0;
      for (int k = 0; k < 4; ++k)
        if (row.node[k] >= 0) hp += row.weight[k] * row.n.dot(p.segment<3>(3 * row.node[k]));
      for (int k = 0; k < 4; ++k)
        if (row.node[k] >= 0) y.segment<3>(3 * row.node[k]) += (c.stiffness * hp * row.weight[k]) * row.n;
    }
  }
  const WarpedSystem& system_;
  const std::vector<char>& fixed_;
};

// z = P r with the CHOLMOD factorisation, optionally rotated per node (Eigen preconditioner interface; the
// factorisation is built by the caller, so analyse/factorise have nothing to do).
class CholmodPreconditioner {
 public:
  void set(const StaticSolver* solver, const std::vector<Eigen::Matrix3d>* node_R) {
    solver_ = solver;
    node_R_ = node_R;
  }
  template <typename M>
  CholmodPreconditioner& analyzePattern(const M&) { return *this; }
  template <typename M>
  CholmodPreconditioner& factorize(const M&) { return *this; }
  template <typename M>
  CholmodPreconditioner& compute(const M&) { return *this; }
  Eigen::ComputationInfo info() const { return Eigen::Success; }
  int applications() const { return applications_; }

  Eigen::VectorXd solve(const Eigen::VectorXd& r) const {
    ++applications_;
    Eigen::VectorXd z;
    if (!node_R_) {
      solver_->solve_approximately(r, z);
      return z;
    }
    // Rn K^-1 Rn^T r, node by node.
    Eigen::VectorXd rl(r.size());
    for (size_t v = 0; v < node_R_->size(); ++v) rl.segment<3>(3 * v) = (*node_R_)[v].transpose() * r.segment<3>(3 * v);
    solver_->solve_approximately(rl, z);
    for (size_t v = 0; v < node_R_->size(); ++v) z.segment<3>(3 * v) = (*node_R_)[v] * z.segment<3>(3 * v).eval();
    return z;
  }

 private:
  const StaticSolver* solver_ = nullptr;
  const std::vector<Eigen::Matrix3d>* node_R_ = nullptr;
  mutable int applications_ = 0;
};

}  // namespace
}  // namespace lumen::physics

namespace Eigen::internal {

// dst += alpha * A * rhs through WarpedOperator::apply.
template <typename Rhs>
struct generic_product_impl<lumen::physics::WarpedOperator, Rhs, SparseShape, DenseShape, GemvProduct>
    : generic_product_impl_base<lumen::physics::WarpedOperator, Rhs,
                                generic_product_impl<lumen::physics::WarpedOperator, Rhs>> {
  template <typename Dest>
  static void scaleAndAddTo(Dest& dst, const lumen::physics::WarpedOperator& lhs, const Rhs& rhs,
                            const double& alpha) {
    const Eigen::VectorXd p = rhs;
    Eigen::VectorXd y;
    lhs.apply(p, y);
    dst += alpha * y;
  }
};

}  // namespace Eigen::internal

namespace lumen::physics {

namespace {

// Checks a PCG call (system, preconditioner, tolerances, b, and x unless empty: then x = 0) and returns the fixed
// DOFs of the factorisation (per DOF, 1 = fixed); per-node rotation needs whole fixed nodes.
std::vector<char> checked_pcg_call(const char* where, const WarpedSystem& system, const StaticSolver& preconditioner,
                                   const Eigen::VectorXd& b, Eigen::VectorXd& x, double tolerance, int max_iterations,
                                   const std::vector<Eigen::Matrix3d>* node_rotations) {
  // Validate the system, the tolerances and the vectors.
  if (!system.elements) throw std::invalid_argument(std::string(where) + ": system.elements must not be null");
  const CorotationalElements& el = *system.elements;
  const int n = el.n_dofs();
  if (!system.rotations) throw std::invalid_argument(std::string(where) + ": system.rotations must not be null");
  if (static_cast<int>(system.rotations->size()) != el.n_tets()) {
    detail::fail_must(where, "system.rotations->size()", ("be n_tets = " + std::to_string(el.n_tets())).c_str(),
         system.rotations->size());
  }
  if (!(system.c_stiffness > 0.0) || !std::isfinite(system.c_stiffness))
    detail::fail_must(where, "system.c_stiffness", "be > 0 and finite", system.c_stiffness);
  if (!(system.c_mass >= 0.0) || !std::isfinite(system.c_mass))
    detail::fail_must(where, "system.c_mass", "be >= 0 and finite", system.c_mass);
  if (system.c_mass > 0.0) {
    if (!system.mass) throw std::invalid_argument(std::string(where) + ": system.mass must not be null when c_mass > 0");
    detail::check_vector(where, "system.mass", *system.mass, n);
  }
  if (system.contacts && (!system.pushing || system.pushing->size() != system.contacts->rows.size()))
    throw std::invalid_argument(std::string(where) + ": system.pushing must hold one flag per contact row");
  if (preconditioner.n_dofs() != n) {
    detail::fail_must(where, "preconditioner.n_dofs()", ("be " + std::to_string(n)).c_str(), preconditioner.n_dofs());
  }
  if (!(tolerance > 0.0 && tolerance < 1.0)) detail::fail_must(where, "tolerance", "be in (0, 1)", tolerance);
  if (max_iterations < 1) detail::fail_must(where, "max_iterations", "be >= 1", max_iterations);
  detail::check_vector(where, "b", b, n);
  if (x.size() == 0) x.setZero(n);
  detail::check_vector(where, "x", x, n);
  // Fixed DOFs of the factorisation; per-node rotation needs whole fixed nodes.
  std::vector<char> fixed(n);
  for (int d = 0; d < n; ++d) fixed[d] = preconditioner.is_fixed_dof(d) ? 1 : 0;
  if (node_rotations) {
    if (static_cast<int>(node_rotations->size()) != el.n_nodes()) {
      detail::fail_must(where, "node_rotations->size()", ("be n_nodes = " + std::to_string(el.n_nodes())).c_str(),
           node_rotations->size());
    }
    for (int v = 0; v < el.n_nodes(); ++v)
      if (fixed[3 * v] != fixed[3 * v + 1] || fixed[3 * v] != fixed[3 * v + 2])
        detail::fail_must(where, "node " + std::to_string(v), "be fixed in all or no components with node_rotations", v);
  }
  return fixed;
}

}  // namespace

PcgResult solve_pcg(const WarpedSystem& system, const StaticSolver& preconditioner, const Eigen::VectorXd& b,
                    Eigen::VectorXd& x, double tolerance, int max_iterations,
                    const std::vector<Eigen::Matrix3d>* node_rotations) {
  const char* where = "solve_pcg";
  std::vector<char> fixed =
      checked_pcg_call(where, system, preconditioner, b, x, tolerance, max_iterations, node_rotations);
  const int n = system.elements->n_dofs();

  // Right-hand side and guess restricted to the free DOFs.
  Eigen::VectorXd bf = b;
  for (int d = 0; d < n; ++d)
    if (fixed[d]) bf[d] = 0.0, x[d] = 0.0;

  // Eigen's preconditioned CG on the matrix-free operator.
  const WarpedOperator A(system, fixed);
  Eigen::ConjugateGradient<WarpedOperator, Eigen::Lower | Eigen::Upper, CholmodPreconditioner> cg;
  cg.preconditioner().set(&preconditioner, node_rotations);
  cg.compute(A);
  cg.setTolerance(tolerance);
  cg.setMaxIterations(max_iterations);
  Eigen::VectorXd guess = x;
  x = cg.solveWithGuess(bf, guess);

  PcgResult result;
  result.iterations = cg.preconditioner().applications();
  result.residual = cg.error();
  result.converged = cg.info() == Eigen::Success;
  return result;
}

PcgResult solve_truncated_pcg(const WarpedSystem& system, const StaticSolver& preconditioner,
                              const Eigen::VectorXd& b, Eigen::VectorXd& x, double tolerance, int max_iterations,
                              const std::vector<Eigen::Matrix3d>* node_rotations) {
  x.resize(0);
  const std::vector<char> fixed = checked_pcg_call("solve_truncated_pcg", system, preconditioner, b, x, tolerance,
                                                   max_iterations, node_rotations);
  const WarpedOperator A(system, fixed);
  CholmodPreconditioner M;
  M.set(&preconditioner, node_rotations);
  // Preconditioned CG from x = 0 (Steihaug 1983 without a trust region): while every search direction has positive
  // curvature each iterate lowers the quadratic model, so b . x > 0; the first direction of non-positive curvature
  // ends it (at the first iteration, the preconditioned residual M^-1 b itself is returned).
  Eigen::VectorXd r = b, Ap;
  for (Eigen::Index d = 0; d < r.size(); ++d)
    if (fixed[d]) r[d] = 0.0;
  const double b_norm = r.norm();
  PcgResult result;
  if (b_norm == 0.0) {
    result.converged = true;
    return result;
  }
  Eigen::VectorXd z = M.solve(r), p = z;
  double rz = r.dot(z);
  for (int k = 0; k < max_iterations; ++k) {
    A.apply(p, Ap);
    const double curvature = p.dot(Ap);
    if (!(curvature > 0.0)) {
      result.negative_curvature = true;
      if (k == 0) x = p;
      break;
    }
    const double alpha = rz / curvature;
    x += alpha * p;
    r -= alpha * Ap;
    result.residual = r.norm() / b_norm;
    if (result.residual <= tolerance) {
      result.converged = true;
      break;
    }
    z = M.solve(r);
    const double rz_next = r.dot(z);
    p = z + (rz_next / rz) * p;
    rz = rz_next;
  }
  result.iterations = M.applications();
  return result;
}

// ---------------------------------------------------------------------------------------------------------------
// CorotationalModel and the quasi-static solve

CorotationalModel::CorotationalModel(const TetMesh& mesh, const LinearMaterial& material,
                                     const std::vector<int>& fixed_nodes, const Eigen::VectorXd& support)
    : elements_(mesh, material, support),
      K_(elements_.with_support(assemble_stiffness(mesh, material))),
      fixed_nodes_(fixed_nodes),
      solver_(K_, fixed_nodes) {
  solver_.add_single_precision();
}

CorotationalModel::CorotationalModel(const QuadraticMesh& mesh, const LinearMaterial& material,
                                     const std::vector<int>& fixed_nodes, const Eigen::VectorXd& support)
    : elements_(mesh, material, support),
      // (The elements' stored K_e unrotated: assemble_stiffness(mesh) would evaluate every K_e a second time.)
      K_(elements_.warped_stiffness(std::vector<Eigen::Matrix3d>(elements_.n_tets(), Eigen::Matrix3d::Identity()))),
      fixed_nodes_(fixed_nodes),
      solver_(K_, fixed_nodes) {
  solver_.add_single_precision();
}

void validate_options(const CorotationalOptions& o) {
  const char* where = "CorotationalOptions";
  if (!(o.tolerance > 0.0) || !std::isfinite(o.tolerance)) detail::fail_must(where, "tolerance", "be > 0 and finite", o.tolerance);
  if (o.max_iterations < 1) detail::fail_must(where, "max_iterations", "be >= 1", o.max_iterations);
  if (!(o.cg_tolerance > 0.0 && o.cg_tolerance < 1.0)) detail::fail_must(where, "cg_tolerance", "be in (0, 1)", o.cg_tolerance);
  if (o.max_cg_iterations < 1) detail::fail_must(where, "max_cg_iterations", "be >= 1", o.max_cg_iterations);
  const int bound = o.max_back_substitutions;
  if (bound < 0 || (bound > 0 && bound < kPcgStepBackSubstitutions))
    detail::fail_must(where, "max_back_substitutions",
                      "be 0 (no bound) or >= " + std::to_string(kPcgStepBackSubstitutions), bound);
  // (Measured: chord steps cut off by a bound, their Anderson history lost with each solve, stall or diverge.)
  if (o.max_back_substitutions != 0 && o.method == CorotationalMethod::chord)
    detail::fail_must(where, "max_back_substitutions", "be 0 with method chord", o.max_back_substitutions);
  const int contact_bound = o.contact_back_substitutions;
  if (contact_bound < 0 || (contact_bound > 0 && contact_bound < kPcgStepBackSubstitutions))
    detail::fail_must(where, "contact_back_substitutions",
                      "be 0 (max_back_substitutions) or >= " + std::to_string(kPcgStepBackSubstitutions), contact_bound);
  if (contact_bound != 0 && o.method == CorotationalMethod::chord)
    detail::fail_must(where, "contact_back_substitutions", "be 0 with method chord", contact_bound);
  if (o.anderson_depth < 0) detail::fail_must(where, "anderson_depth", "be >= 0", o.anderson_depth);
  if (o.refactor_cg_iterations < 0) detail::fail_must(where, "refactor_cg_iterations", "be >= 0", o.refactor_cg_iterations);
  if (o.method == CorotationalMethod::chord && o.tangent != CorotationalTangent::warped)
    throw std::invalid_argument(std::string(where) + ": method chord needs tangent warped (the factorisation is K_w's)");
}

namespace {

// The quasi-static residual at state.u on the free DOFs: rotations and elastic forces (reused from the last
// evaluation while u has not changed), r = f - f_int, and |r| relative to the loads or the support reactions.
class CorotationalResidual {
 public:
  CorotationalResidual(const CorotationalElements& el, CorotationalState& state, const Eigen::VectorXd& f,
                       const std::vector<char>& fixed, const AugmentedContacts* contacts)
      : el_(el), state_(state), f_(f), fixed_(fixed), contacts_(contacts), r_(f.size()) {}

  double evaluate() {
    const int n = static_cast<int>(f_.size());
    evaluate_at_u(el_, state_);
    for (int d = 0; d < n; ++d) r_[d] = fixed_[d] ? 0.0 : f_[d] - state_.f_int[d];
    scale_ = std::max(f_.norm(), detail::reaction_norm(state_.f_int, fixed_));
    if (contacts_) add_contact_forces();
    rnorm_ = r_.norm();
    return rnorm_ == 0.0 ? 0.0 : (scale_ > 0.0 ? rnorm_ / scale_ : INFINITY);
  }
  const Eigen::VectorXd& r() const { return r_; }
  // The potential Pi(u) whose negative gradient r is, at the last evaluation: elastic energy, minus the free
  // loads' work, plus each carried row's augmented term max(0, lambda_eff)^2 / (2 stiffness); joules.
  double potential() const {
    double pi = state_.energy - f_.dot(state_.u);  // (evaluate_at_u's, at u)
    if (contacts_) pi += lambda_eff_.squaredNorm() / (2.0 * contacts_->stiffness);
    return pi;
  }
  double scale() const { return scale_; }  // force scale, newtons
  double norm() const { return rnorm_; }   // |r|, newtons
  const Eigen::VectorXd& contact_lambda() const { return lambda_eff_; }  // lambda_eff per carried row, newtons
  const std::vector<char>& pushing() const { return pushing_; }           // per carried row: lambda_eff > 0

 private:
  // The carried contacts' forces H^T lambda_eff at state.u join the residual (and its force scale).
  void add_contact_forces() {
    const AugmentedContacts& c = *contacts_;
    const Eigen::VectorXd h = row_values(c.rows, state_.u);
    lambda_eff_.resize(static_cast<Eigen::Index>(c.rows.size()));
    pushing_.assign(c.rows.size(), 0);
    for (size_t r = 0; r < c.rows.size(); ++r) {
      const Eigen::Index i = static_cast<Eigen::Index>(r);
      lambda_eff_[i] = std::max(0.0, c.lambda[i] + c.stiffness * (c.rows[r].g - h[i]));
      pushing_[r] = lambda_eff_[i] > 0.0 ? 1 : 0;
    }
    const Eigen::VectorXd fc = contact_force(c.rows, lambda_eff_, static_cast<int>(r_.size()));
    for (Eigen::Index d = 0; d < r_.size(); ++d)
      if (!fixed_[d]) r_[d] += fc[d];
    scale_ = std::max(scale_, fc.norm());
  }
  const CorotationalElements& el_;
  CorotationalState& state_;
  const Eigen::VectorXd& f_;
  const std::vector<char>& fixed_;
  const AugmentedContacts* contacts_;
  Eigen::VectorXd lambda_eff_;
  std::vector<char> pushing_;
  Eigen::VectorXd r_;
  double scale_ = 0.0, rnorm_ = 0.0;
};

// Fixed DOFs take the prescribed values (u_fixed, empty = 0) and carry no load; with no load and nothing
// prescribed the state goes back to rest. Fills the fixed mask and the free loads f.
void prescribe(const CorotationalModel& model, const Eigen::VectorXd& f_ext, const Eigen::VectorXd& u_fixed,
               CorotationalState& state, std::vector<char>& fixed, Eigen::VectorXd& f) {
  const int n = model.n_dofs();
  fixed.assign(n, 0);
  f = f_ext;
  bool any_prescribed = false;
  for (int d = 0; d < n; ++d) {
    fixed[d] = model.is_fixed_dof(d) ? 1 : 0;
    if (!fixed[d]) continue;
    f[d] = 0.0;
    state.u[d] = u_fixed.size() ? u_fixed[d] : 0.0;
    any_prescribed = any_prescribed || state.u[d] != 0.0;
  }
  if (!any_prescribed && f.isZero(0.0)) state.u.setZero();
}

// Secant predictor u + (u - u_before) on the free DOFs, kept only when it lowers the residual (refused: the next
// kSecantRetryAfter solves do not try it); returns the residual at the kept start.
double extrapolate_start(CorotationalState& state, CorotationalResidual& residual, const std::vector<char>& fixed,
                         const Eigen::VectorXd& u_before, double residual_now) {
  CachedEvaluation saved;
  saved.swap_evaluation(state);
  const Eigen::VectorXd u_start = state.u;
  for (Eigen::Index d = 0; d < state.u.size(); ++d)
    if (!fixed[d]) state.u[d] += state.u[d] - u_before[d];
  const double predicted = residual.evaluate();
  if (predicted < residual_now) return predicted;
  // Refused: back to the start, and the next solves do not try it.
  state.secant_skips = kSecantRetryAfter;
  state.u = u_start;
  saved.swap_evaluation(state);
  return residual.evaluate();  // cached: no new evaluation
}

// Anderson acceleration (type II, Walker & Ni 2011) of the fixed-point map u -> u + du(u): the next iterate
// u + du - (dX + dF) gamma, gamma minimising |du - dF gamma| over the last `depth` differences of iterates (dX)
// and steps (dF). Depth 0: the plain step.
class AndersonMixing {
 public:
  explicit AndersonMixing(int depth) : depth_(depth) {}
  // Moves u by the mixed step; returns whether it mixed (false: u += du, the plain step).
  bool mix(Eigen::VectorXd& u, const Eigen::VectorXd& du) {
    if (depth_ == 0) {
      u += du;
      return false;
    }
    // The differences since the last iterate, the oldest dropped past the depth.
    if (last_u_.size() == u.size()) {
      dX_.push_back(u - last_u_);
      dF_.push_back(du - last_du_);
      if (static_cast<int>(dX_.size()) > depth_) dX_.erase(dX_.begin()), dF_.erase(dF_.begin());
    }
    last_u_ = u;
    last_du_ = du;
    if (dX_.empty()) {
      u += du;
      return false;
    }
    const int m = static_cast<int>(dF_.size());
    Eigen::MatrixXd F(du.size(), m), X(du.size(), m);
    for (int j = 0; j < m; ++j) F.col(j) = dF_[j], X.col(j) = dX_[j];
    const Eigen::VectorXd gamma = F.colPivHouseholderQr().solve(du);
    if (!gamma.allFinite()) {
      u += du;
      return false;
    }
    u += du - (X + F) * gamma;
    return true;
  }
  // The history of an earlier solve (pairs of another length are dropped; at most `depth` of the newest kept):
  // its pairs mix the first step, the new pairs start from this solve's first iterate.
  void resume(std::vector<Eigen::VectorXd> dX, std::vector<Eigen::VectorXd> dF, int n) {
    clear();
    if (depth_ == 0 || dX.size() != dF.size() || (!dX.empty() && (dX[0].size() != n || dF[0].size() != n))) return;
    const size_t first = dX.size() > static_cast<size_t>(depth_) ? dX.size() - depth_ : 0;
    dX_.assign(std::make_move_iterator(dX.begin() + first), std::make_move_iterator(dX.end()));
    dF_.assign(std::make_move_iterator(dF.begin() + first), std::make_move_iterator(dF.end()));
  }
  // Hands the history over (for the next solve) and forgets it.
  void hand_over(std::vector<Eigen::VectorXd>& dX, std::vector<Eigen::VectorXd>& dF) {
    dX = std::move(dX_);
    dF = std::move(dF_);
    clear();
  }
  // Forget the history (a mixed step that did not help).
  void clear() {
    dX_.clear();
    dF_.clear();
    last_u_.resize(0);
  }

 private:
  int depth_;
  std::vector<Eigen::VectorXd> dX_, dF_;  // per kept pair: iterate and step differences, 3n each
  Eigen::VectorXd last_u_, last_du_;
};

// Carried contacts: a positive finite stiffness, one finite multiplier >= 0 per row, row nodes in the mesh.
void validate_contacts(const char* where, const AugmentedContacts& c, int n_nodes) {
  if (!(c.stiffness > 0.0) || !std::isfinite(c.stiffness))
    detail::fail_must(where, "contacts.stiffness", "be > 0 and finite", c.stiffness);
  if (c.lambda.size() != static_cast<Eigen::Index>(c.rows.size()))
    detail::fail_must(where, "contacts.lambda.size()", ("be rows = " + std::to_string(c.rows.size())).c_str(),
                      c.lambda.size());
  for (Eigen::Index r = 0; r < c.lambda.size(); ++r)
    if (!(c.lambda[r] >= 0.0) || !std::isfinite(c.lambda[r]))
      detail::fail_must(where, "contacts.lambda[" + std::to_string(r) + "]", "be >= 0 and finite", c.lambda[r]);
  for (size_t r = 0; r < c.rows.size(); ++r)
    for (int k = 0; k < 4; ++k)
      if (c.rows[r].node[k] >= n_nodes)
        detail::fail_must(where, "contacts.rows[" + std::to_string(r) + "].node[" + std::to_string(k) + "]",
                          ("be a node id < " + std::to_string(n_nodes)).c_str(), c.rows[r].node[k]);
}

// A background factorisation that has finished becomes the preconditioner; one that failed is dropped, keeps the
// current preconditioner and is counted (never silently).
void adopt_finished_factorisation(CorotationalState& state, CorotationalResult& result) {
  if (!state.pending.valid() || state.pending.wait_for(std::chrono::seconds(0)) != std::future_status::ready) return;
  try {
    state.preconditioner = state.pending.get();  // (get() leaves pending invalid, failed or not)
    state.preconditioner_node_rotations = std::move(state.pending_node_rotations);
  } catch (const std::exception&) {
    ++result.refactor_failures;
  }
}

// Factorise K_w at the current rotations for the solves to come: on a background thread, or now.
void start_factorisation(const CorotationalModel& model, const CorotationalOptions& options, CorotationalState& state,
                         CorotationalResult& result) {
  ++result.refactorisations;
  const CorotationalElements& el = model.elements();
  const std::vector<int>& fixed_nodes = model.fixed_nodes();
  // The matrix: K_w, or with a tangent the projected tangent at the current iterate (positive semi-definite;
  // the exact tangent may be indefinite, which a Cholesky factorisation cannot take).
  // (The projected tangent's modes are the solve's own; the exact tangent's are projected here.)
  const bool tangent = options.tangent != CorotationalTangent::warped;
  std::vector<TwistModes> twist;
  if (options.tangent == CorotationalTangent::projected)
    twist = state.twist;
  else if (tangent)
    el.twist_modes(state.u, state.rotations, /*project=*/true, twist);
  // (On the rest factorisation's symbolic analysis when the pattern is K's, as it is for the kernels' matrices:
  // the ordering and supernodes are the same, only the numbers change.)
  const StaticSolver& rest = model.solver();
  auto factorise = [&el, &fixed_nodes, &rest, tangent](std::vector<Eigen::Matrix3d> R, std::vector<TwistModes> modes) {
    Eigen::SparseMatrix<double> K = tangent ? el.tangent_stiffness(R, modes) : el.warped_stiffness(R);
    using Solver = std::shared_ptr<const StaticSolver>;
    if (rest.has_pattern(K)) return Solver(std::make_shared<StaticSolver>(rest.refactorised(std::move(K))));
    return Solver(std::make_shared<StaticSolver>(K, fixed_nodes));
  };
  // The nodes' rotations the factor is taken at (for preconditioning it turned by their rotation since).
  std::vector<Eigen::Matrix3d> node_R;
  if (options.rotate_preconditioner) el.node_rotations(state.rotations, node_R);
  if (options.refactor_in_background) {
    state.pending_node_rotations = std::move(node_R);
    auto in_background = [factorise](std::vector<Eigen::Matrix3d> R, std::vector<TwistModes> modes) {
      at_background_priority();  // (this thread only)
      return factorise(std::move(R), std::move(modes));
    };
    state.pending = std::async(std::launch::async, in_background, state.rotations, std::move(twist));
    return;
  }
  try {
    state.preconditioner = factorise(state.rotations, std::move(twist));
    state.preconditioner_node_rotations = std::move(node_R);
  } catch (const std::exception&) {
    ++result.refactor_failures;  // not positive definite or out of memory: keep the current preconditioner
  }
}

// Moves state.u by du or by its Anderson mix, whichever lowers the residual (the plain step when the mix does
// not, and the history restarts); residual: the new one.
void take_step(CorotationalState& state, CorotationalResidual& residual_at, AndersonMixing& anderson,
               const Eigen::VectorXd& du, double before, double& residual) {
  const Eigen::VectorXd u_start = state.u;
  const bool mixed = anderson.mix(state.u, du);
  residual = residual_at.evaluate();
  if (mixed && !(residual < before)) {
    state.u = u_start + du;
    anderson.clear();
    residual = residual_at.evaluate();
  }
}

// The solve's start (displacement, evaluation, |r|), to go back to when its residual diverges.
class DivergenceGuard {
 public:
  DivergenceGuard(const CorotationalState& state, const CorotationalResidual& residual)
      : start_norm_(residual.norm()) {
    start_.take(state);
  }
  // After a step: when |r| is non-finite or above kDivergenceGrowth times the start's, restores the start, marks
  // the result diverged (not converged, its residual the start's) and asks for a factorisation at the start's
  // rotations (unless one is under way), so that the next solve has an operator near its tangent. Returns whether
  // the solve must stop.
  bool diverged(const CorotationalModel& model, const CorotationalOptions& options, CorotationalState& state,
                CorotationalResidual& residual, CorotationalResult& result) const {
    if (residual.norm() <= kDivergenceGrowth * start_norm_) return false;  // (false for NaN too)
    start_.restore(state);
    result.residual = residual.evaluate();  // (cached: the start's residual and contact forces again)
    result.n_inverted = state.n_inverted;
    result.converged = false;
    result.diverged = true;
    if (!state.pending.valid()) start_factorisation(model, options, state, result);
    return true;
  }

 private:
  CachedEvaluation start_;
  double start_norm_;  // |r| at the start, newtons
};

// Newton's step du on the exact tangent: kept when it descends the potential (du . r > 0, r = -grad Pi) and a
// backtracking line search finds Armijo's sufficient decrease; returns whether state.u moved (residual: the new
// one). Otherwise state.u is left at a trial point for the caller to restore.
bool newton_step(CorotationalState& state, CorotationalResidual& residual_at, const Eigen::VectorXd& du,
                 double& residual) {
  const double slope = du.dot(residual_at.r());
  if (!(slope > 0.0)) return false;
  const double start = residual_at.potential();
  const Eigen::VectorXd u0 = state.u;
  double alpha = 1.0;
  for (int k = 0; k <= kMaxBacktracks; ++k, alpha *= 0.5) {
    state.u = u0 + alpha * du;
    residual = residual_at.evaluate();
    if (residual_at.potential() <= start - kArmijo * alpha * slope) return true;
  }
  return false;
}

// Back-substitutions left of the solve's work bound (options.max_back_substitutions; INT_MAX without one). A PCG
// step of k iterations takes k + 1, so it needs kPcgStepBackSubstitutions left and gets at most left - 1 iterations.
int back_substitutions_left(const CorotationalOptions& options, const CorotationalResult& result) {
  if (options.max_back_substitutions == 0) return std::numeric_limits<int>::max();
  return options.max_back_substitutions - result.cg_iterations;
}

// Chord iterations (CorotationalMethod::chord): du = A^-1 r with A the lagged factorisation (the rest one until
// the first refresh), one back-substitution a step, Anderson-mixed; a refresh of the factorisation at the current
// rotations is asked for every options.refactor_cg_iterations steps, counted over solves (on the background
// thread, or at once). result: in the start's residual, out the end's.
void chord_iterations(const CorotationalModel& model, const CorotationalOptions& options, CorotationalState& state,
                      CorotationalResidual& residual, CorotationalResult& result) {
  AndersonMixing anderson(options.anderson_depth);
  Eigen::VectorXd du;
  DivergenceGuard guard(state, residual);
  for (;;) {
    result.n_inverted = state.n_inverted;
    result.converged = result.residual <= options.tolerance;
    if (result.converged || result.iterations >= options.max_iterations) break;
    adopt_finished_factorisation(state, result);
    if (options.refactor_cg_iterations > 0 && state.chord_steps_since_refresh >= options.refactor_cg_iterations &&
        !state.pending.valid()) {
      start_factorisation(model, options, state, result);
      state.chord_steps_since_refresh = 0;
    }
    ++state.chord_steps_since_refresh;
    // The step on the lagged factorisation, mixed with the last ones when that lowers the residual.
    const StaticSolver& A = state.preconditioner ? *state.preconditioner : model.solver();
    A.solve_approximately(residual.r(), du);
    ++result.iterations;
    ++result.cg_iterations;
    if (!du.allFinite()) break;  // keep the last finite iterate (not converged)
    take_step(state, residual, anderson, du, result.residual, result.residual);
    if (guard.diverged(model, options, state, residual, result)) break;
  }
}

}  // namespace

void at_background_priority() { setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), kBackgroundFactorisationNice); }

void evaluate_at_u(const CorotationalElements& el, CorotationalState& state) {
  const int n = el.n_dofs();
  const bool cached = state.u_eval.size() == n && static_cast<int>(state.rotations.size()) == el.n_tets() &&
                      state.f_int.size() == n && state.u_eval == state.u;
  if (cached) return;
  state.n_inverted = el.rotations_and_forces(state.u, state.rotations, state.f_int, &state.energy);
  state.u_eval = state.u;
}

std::shared_ptr<const StaticSolver> factorise_warped(const CorotationalModel& model,
                                                     const std::vector<Eigen::Matrix3d>& R, bool half_columns) {
  Eigen::SparseMatrix<double> K = model.elements().warped_stiffness(R);
  // (On the rest factorisation's analysis when the pattern is K's, as start_factorisation does; with half columns on
  // its nested-dissection analysis when made, one factorisation serving both.)
  const StaticSolver& rest = model.solver();
  std::shared_ptr<StaticSolver> solver;
  if (!rest.has_pattern(K))
    solver = std::make_shared<StaticSolver>(K, model.fixed_nodes());
  else if (half_columns && rest.has_nested_analysis())
    solver = std::make_shared<StaticSolver>(rest.refactorised_nested(std::move(K)));
  else
    solver = std::make_shared<StaticSolver>(rest.refactorised(std::move(K)));
  if (half_columns) solver->prepare_half_columns();
  return solver;
}

CorotationalResult solve_corotational(const CorotationalModel& model, const Eigen::VectorXd& f_ext,
                                      CorotationalState& state, const CorotationalOptions& options,
                                      const Eigen::VectorXd& u_fixed, const AugmentedContacts* contacts) {
  const char* where = "solve_corotational";
  validate_options(options);
  const CorotationalElements& el = model.elements();
  if (options.tangent != CorotationalTangent::warped) el.require_linear(where);
  const int n = model.n_dofs();
  detail::check_vector(where, "f_ext", f_ext, n);
  if (u_fixed.size() != 0) detail::check_vector(where, "u_fixed", u_fixed, n);
  if (contacts) validate_contacts(where, *contacts, el.n_nodes());
  if (state.u.size() == 0) state.u.setZero(n);
  detail::check_vector(where, "state.u", state.u, n);
  const bool can_extrapolate = options.extrapolate && state.u_previous.size() == n && state.secant_skips == 0;
  if (state.secant_skips > 0) --state.secant_skips;
  const Eigen::VectorXd u_before = can_extrapolate ? state.u_previous : Eigen::VectorXd();
  state.u_previous = state.u;

  // Prescribed DOFs, the residual at the start, the secant start when it is better.
  std::vector<char> fixed;
  Eigen::VectorXd f;
  prescribe(model, f_ext, u_fixed, state, fixed, f);
  CorotationalResult result;
  CorotationalResidual residual(el, state, f, fixed, contacts);
  result.residual = residual.evaluate();
  if (can_extrapolate && result.residual > options.tolerance)
    result.residual = extrapolate_start(state, residual, fixed, u_before, result.residual);

  if (options.method == CorotationalMethod::chord) {
    chord_iterations(model, options, state, residual, result);
    if (contacts) result.contact_lambda = residual.contact_lambda();
    return result;
  }

  // Fixed-point iterations on the warped system, or Newton's on the tangent (the Anderson history of the last
  // solve resumed when carried; as within a solve, a mixed step that does not lower the residual restarts it).
  AndersonMixing anderson(options.anderson_depth);
  if (options.carry_anderson_history)
    anderson.resume(std::move(state.anderson_dX), std::move(state.anderson_dF), n);
  state.anderson_dX.clear(), state.anderson_dF.clear();
  DivergenceGuard guard(state, residual);
  Eigen::VectorXd du;
  std::vector<Eigen::Matrix3d> node_R;
  for (;;) {
    result.n_inverted = state.n_inverted;
    result.converged = result.residual <= options.tolerance;
    if (result.converged || result.iterations >= options.max_iterations) break;
    if (back_substitutions_left(options, result) < kPcgStepBackSubstitutions) break;  // the bound is spent
    adopt_finished_factorisation(state, result);
    // The operator: K_w, or the tangent with the twist modes at u (trivial at rest, where K_t = K_w).
    bool tangent_step = false;
    if (options.tangent != CorotationalTangent::warped) {
      el.twist_modes(state.u, state.rotations, options.tangent == CorotationalTangent::projected, state.twist);
      for (const TwistModes& m : state.twist) tangent_step = tangent_step || !m.stiffness.isZero(0.0);
    }
    // Linear solve A du = r by PCG (the lagged factorisation or the rest one as preconditioner), no more
    // accurate than needed.
    auto linear_step = [&](bool with_tangent, bool may_refactor) {
      const StaticSolver& preconditioner = state.preconditioner ? *state.preconditioner : model.solver();
      // (A lagged factor turns by the nodes' rotations since it was factorised, R_now R_then^T; one factorised
      // without them stays as it is.)
      const std::vector<Eigen::Matrix3d>& then = state.preconditioner_node_rotations;
      const bool rotate = options.rotate_preconditioner &&
                          (!state.preconditioner || static_cast<int>(then.size()) == el.n_nodes());
      const WarpedSystem system{&el, &state.rotations, nullptr, 0.0, 1.0, contacts, &residual.pushing(),
                                with_tangent ? &state.twist : nullptr};
      if (rotate) {
        el.node_rotations(state.rotations, node_R);
        if (state.preconditioner)
          for (size_t v = 0; v < node_R.size(); ++v) node_R[v] = node_R[v] * then[v].transpose();
      }
      const double cg_tol =
          std::max(options.cg_tolerance, std::min(0.5, 0.5 * options.tolerance * residual.scale() / residual.norm()));
      du.resize(0);
      // (Newton's steps on the exact tangent by truncated CG: a descent direction even where it is indefinite.)
      const int max_cg = std::min(options.max_cg_iterations, back_substitutions_left(options, result) - 1);
      const PcgResult pcg =
          with_tangent && options.tangent == CorotationalTangent::exact
              ? solve_truncated_pcg(system, preconditioner, residual.r(), du, cg_tol, max_cg, rotate ? &node_R : nullptr)
              : solve_pcg(system, preconditioner, residual.r(), du, cg_tol, max_cg, rotate ? &node_R : nullptr);
      result.cg_iterations += pcg.iterations;
      result.truncated_steps += pcg.negative_curvature ? 1 : 0;
      // A slow solve, or one the work bound cut short: factorise at these rotations for the solves to come
      // (unless one is under way).
      // (A truncated step that met negative curvature was not cut short: it says little about the preconditioner.)
      const bool cut_short = !pcg.converged && !pcg.negative_curvature && max_cg < options.max_cg_iterations;
      const bool slow = pcg.iterations > options.refactor_cg_iterations || cut_short;
      if (may_refactor && options.refactor_cg_iterations > 0 && slow && !state.pending.valid())
        start_factorisation(model, options, state, result);
    };
    ++result.iterations;
    const double before = result.residual;
    if (tangent_step && options.tangent == CorotationalTangent::exact) {
      // Newton's step on the exact tangent (truncated CG: a descent direction), line-searched on the potential;
      // where the search finds no decrease, the warped step from the same start instead.
      // (A slow solve on the indefinite tangent says little about the preconditioner: at most one factorisation
      // a solve comes from these steps.)
      CachedEvaluation start;
      start.take(state);
      linear_step(true, result.refactorisations == 0);
      if (du.allFinite() && newton_step(state, residual, du, result.residual)) {
        anderson.clear();
        continue;
      }
      start.restore(state);
      result.residual = residual.evaluate();  // (cached: the start's residual and contact forces again)
      ++result.tangent_fallbacks;
      tangent_step = false;
      if (back_substitutions_left(options, result) < kPcgStepBackSubstitutions) break;  // the bound is spent
    }
    // The step: du, or its Anderson-mixed version when that lowers the residual.
    linear_step(tangent_step, true);
    if (!du.allFinite()) break;  // keep the last finite iterate (not converged)
    take_step(state, residual, anderson, du, before, result.residual);
    if (guard.diverged(model, options, state, residual, result)) {
      anderson.clear();
      break;
    }
  }
  if (options.carry_anderson_history) anderson.hand_over(state.anderson_dX, state.anderson_dF);
  if (contacts) result.contact_lambda = residual.contact_lambda();
  return result;
}

}  // namespace lumen::physics
