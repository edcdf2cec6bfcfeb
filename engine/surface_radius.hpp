#pragma once
// A swept tube's lumen radius sampled from the organ's surface (mesh.radius {"from_surface": FILE}): in each
// ring's plane, rays from the centreline point to the surface; their median distance, smoothed along the arc
// length, becomes the tube's radius profile (so the bend clamp still applies to it).
#include <string>
#include <vector>

#include "engine/surface_file.hpp"
#include "physics/swept_tube.hpp"

namespace lumen::engine {

// Rays cast from each ring's centre in its plane, at equal angles from the ring's local x axis.
inline constexpr int kRadiusRays = 16;
// More than this fraction of a ring's rays must meet the surface from inside (leaving the lumen through a
// triangle that faces along the ray) for the ring to have a radius.
inline constexpr double kMinRadiusRayFraction = 0.5;
// Half the window of the moving mean along the arc length that smooths the sampled radii, metres (the rings
// within 5 mm on either side: one haustral fold is 20-30 mm long, so the folds stay, a single ring's outlier goes).
inline constexpr double kRadiusSmoothingHalfWindow = 0.005;

// The lumen radius at every ring of the spec (physics::swept_tube_ring_frames; the spec's centreline, range and
// segment_length must be valid), as a profile of knots at the rings' arc lengths: in each ring's plane, the
// median of the distances along kRadiusRays rays from the ring's centre to the first triangle of `surface` they
// meet (closed and facing outwards, metres), counting only rays that leave the lumen there; then smoothed
// (physics::smooth_profile, kRadiusSmoothingHalfWindow).
// Why the median: the lumen's cross-section is not a circle. The minimum over the rays (and the nearest surface
// point, which is never further) follows the deepest fold or the flattest side of every ring and gives a tube
// much narrower than the lumen; the mean is pulled by the odd long ray that runs along a fold or out through a
// neighbouring loop that touches. The median is the typical wall distance, and up to half the rays may be wild.
// Throws InputError "FILE: ring J (arc length S m, centreline point [x, y, z] m): its plane misses the surface:
// K of 16 rays from the centreline meet it from inside (at least 9 needed)" for a ring whose centre is outside
// the surface or whose plane misses it.
std::vector<physics::RadiusKnot> sample_lumen_radius(const physics::SweptTubeSpec& spec, const SurfaceMesh& surface,
                                                     const std::string& file);

}  // namespace lumen::engine
