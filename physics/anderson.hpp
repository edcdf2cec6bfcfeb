#pragma once
// Anderson acceleration of a fixed-point iteration (the corotational solve's steps, the contact equilibrium's).
#include <vector>

#include <Eigen/Dense>

namespace lumen::physics {

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

}  // namespace lumen::physics
