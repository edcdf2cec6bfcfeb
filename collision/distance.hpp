#pragma once
// Closest points between primitives (Ericson, Real-Time Collision Detection, 5.1.5 and 5.1.9).
#include <Eigen/Dense>

namespace lumen::collision {

// Barycentric weights (wa, wb, wc), summing to 1, of the point of triangle abc closest to p.
Eigen::Vector3d closest_on_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                    const Eigen::Vector3d& c);

// Distance from p to triangle abc, metres.
double point_triangle_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                               const Eigen::Vector3d& c);

// Parameters s (on ab) and t (on cd), in [0, 1], of the closest points of segments ab and cd.
void segment_segment_closest(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                             const Eigen::Vector3d& d, double& s, double& t);

// Distance between segments ab and cd (degenerate segments allowed), metres.
double segment_segment_distance(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                                const Eigen::Vector3d& d);

}  // namespace lumen::collision
