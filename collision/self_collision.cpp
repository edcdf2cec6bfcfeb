// Self-collision: one collision surface and one refit workspace together (see collision/surface.cpp).
#include "collision/self_collision.hpp"

namespace lumen::collision {

SelfCollision::SelfCollision(const TrisRef& tris, int n_points, int kdop)
    : workspace_(kdop), surface_(tris, n_points) {}

SelfCollision::SelfCollision(const TrisRef& tris, const PointsRef& rest, int kdop)
    : workspace_(kdop), surface_(tris, rest) {}

SelfCollision::~SelfCollision() = default;
SelfCollision::SelfCollision(SelfCollision&&) noexcept = default;
SelfCollision& SelfCollision::operator=(SelfCollision&&) noexcept = default;

void SelfCollision::rebuild(const PointsRef& x) { surface_.build_bvh(x); }

void SelfCollision::detect(const PointsRef& x0, const PointsRef& x1, double gap, std::vector<Contact>& out,
                           CollisionStats* stats) {
  if (!surface_.has_bvh()) {
    // First call without a rest-built topology: build it over x0 (once the motion is known valid).
    validate_motion(surface_, x0, x1, gap);
    surface_.build_bvh(x0);
  }
  detect_self(surface_, workspace_, x0, x1, gap, out, stats);
}

void SelfCollision::detect_brute_force(const PointsRef& x0, const PointsRef& x1, double gap,
                                       std::vector<Contact>& out, CollisionStats* stats) {
  detect_self_brute_force(surface_, workspace_, x0, x1, gap, out, stats);
}

const std::vector<FeaturePair>& SelfCollision::tested_features() const { return workspace_.tested_features(); }
int SelfCollision::kdop() const { return workspace_.kdop(); }
void SelfCollision::set_classify_overlaps(bool on) { workspace_.set_classify_overlaps(on); }
SelfCollision::OverlapTotals SelfCollision::overlap_totals() const { return workspace_.overlap_totals(); }
int SelfCollision::num_points() const { return surface_.num_points(); }
int SelfCollision::num_triangles() const { return surface_.num_triangles(); }
int SelfCollision::num_edges() const { return surface_.num_edges(); }

}  // namespace lumen::collision
