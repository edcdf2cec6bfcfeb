// A swept tube's lumen radius from the organ's surface: rays in each ring's plane, the median, smoothed.
#include "engine/surface_radius.hpp"

#include <algorithm>
#include <cmath>

#include "collision/raycast.hpp"
#include "engine/input.hpp"
#include "engine/scene.hpp"

namespace lumen::engine {
namespace {

// The median of a non-empty list (the mean of the middle two of an even count).
double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const size_t h = v.size() / 2;
  return v.size() % 2 ? v[h] : 0.5 * (v[h - 1] + v[h]);
}

// The distances from the frame's centre, along kRadiusRays rays in its plane, to the surface where the rays
// leave the lumen (the first triangle met faces along the ray); rays that meet nothing or enter a triangle from
// outside are left out.
std::vector<double> ring_ray_distances(const physics::CentrelineFrame& f, const SurfaceMesh& surface,
                                       const collision::RayCaster& caster) {
  std::vector<double> d;
  for (int i = 0; i < kRadiusRays; ++i) {
    const Eigen::Vector3d dir = physics::ring_point(f, 1.0, physics::kTwoPi * i / kRadiusRays) - f.point;
    const collision::RayHit hit = caster.first_hit(f.point.data(), dir.data());
    if (!hit.hit()) continue;
    const Eigen::Vector3d a = surface.points.row(surface.tris(hit.triangle, 0));
    const Eigen::Vector3d b = surface.points.row(surface.tris(hit.triangle, 1));
    const Eigen::Vector3d c = surface.points.row(surface.tris(hit.triangle, 2));
    if ((b - a).cross(c - a).dot(dir) > 0.0) d.push_back(hit.t);
  }
  return d;
}

}  // namespace

std::vector<physics::RadiusKnot> sample_lumen_radius(const physics::SweptTubeSpec& spec, const SurfaceMesh& surface,
                                                     const std::string& file) {
  const collision::RayCaster caster(surface.points, surface.tris);
  const physics::RingFrames rings = physics::swept_tube_ring_frames(spec);
  const int needed = static_cast<int>(std::floor(kMinRadiusRayFraction * kRadiusRays)) + 1;
  std::vector<double> radius;
  for (size_t j = 0; j < rings.s.size(); ++j) {
    const physics::CentrelineFrame& f = rings.frames[j];
    const std::vector<double> d = ring_ray_distances(f, surface, caster);
    if (static_cast<int>(d.size()) < needed)
      throw InputError(file + ": ring " + std::to_string(j) + " (arc length " + value_text(rings.s[j]) +
                       " m, centreline point " + values_text(f.point.data(), 3) + " m): its plane misses the surface: " +
                       std::to_string(d.size()) + " of " + std::to_string(kRadiusRays) +
                       " rays from the centreline meet it from inside (at least " + std::to_string(needed) + " needed)");
    radius.push_back(median(d));
  }
  const double step = rings.s.size() > 1 ? rings.s[1] - rings.s[0] : 1.0;
  const std::vector<double> smooth = physics::smooth_profile(radius, step, kRadiusSmoothingHalfWindow);
  std::vector<physics::RadiusKnot> knots;
  for (size_t j = 0; j < smooth.size(); ++j) knots.push_back({rings.s[j], smooth[j]});
  return knots;
}

}  // namespace lumen::engine
