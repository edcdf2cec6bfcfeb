// Self-collision: swept k-DOP BVH vs all pairs of triangle k-DOPs on the paper's tube (20 x 26 inner wall,
// 1040 triangles) with the walls pushed toward each other; and the exact intersection count per frame.
#include <benchmark/benchmark.h>

#include <cmath>
#include <vector>

#include "collision/kdop.hpp"
#include "collision/self_collision.hpp"

namespace {

using Points = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
using Tris = Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor>;
using lumen::collision::CollisionStats;
using lumen::collision::Contact;
using lumen::collision::SelfCollision;

constexpr double kPi = static_cast<double>(EIGEN_PI);  // Eigen's constant, a long double, as a double
constexpr double kRadius = 0.015;  // inner radius, metres
constexpr double kLength = 0.1;    // metres
constexpr double kGap = 1e-4;      // contact distance, metres

// The inner wall: nz x nth quads along z, 2 triangles each; x0 -> x1 one frame of a pinch at mid-length
// that brings the walls from 10 % of the diameter apart to touching.
struct BvhScene {
  Points rest, x0, x1;
  Tris tris;
};

BvhScene make_bvh_scene() {
  const int nz = 20, nth = 26;
  BvhScene s;
  s.rest.resize((nz + 1) * nth, 3);
  for (int k = 0; k <= nz; ++k) {
    for (int j = 0; j < nth; ++j) {
      const double th = 2.0 * kPi * j / nth;
      s.rest.row(k * nth + j) << kRadius * std::cos(th), kRadius * std::sin(th), kLength * k / nz;
    }
  }
  s.tris.resize(2 * nz * nth, 3);
  for (int k = 0; k < nz; ++k) {
    for (int j = 0; j < nth; ++j) {
      const int v00 = k * nth + j, v01 = k * nth + (j + 1) % nth;
      const int v10 = (k + 1) * nth + j, v11 = (k + 1) * nth + (j + 1) % nth;
      s.tris.row(2 * (k * nth + j)) << v00, v01, v11;
      s.tris.row(2 * (k * nth + j) + 1) << v00, v11, v10;
    }
  }
  s.x0 = s.rest;
  s.x1 = s.rest;
  for (int i = 0; i < s.rest.rows(); ++i) {
    const double g = std::exp(-std::pow((s.rest(i, 2) - 0.5 * kLength) / (0.2 * kLength), 2));
    s.x0(i, 1) *= 1.0 - 0.9 * g;
    s.x1(i, 1) *= 1.0 - 1.0 * g;
  }
  return s;
}

void set_counters(benchmark::State& state, const CollisionStats& st) {
  state.counters["bv_overlaps"] = static_cast<double>(st.bv_overlaps);
  state.counters["feature_tests"] = static_cast<double>(st.feature_tests);
  state.counters["contacts"] = static_cast<double>(st.contacts);
}

// One frame of detection through the BVH (refit, self-traversal, deduplicated features, CCD).
void BM_SelfCollisionBvh(benchmark::State& state) {
  const BvhScene s = make_bvh_scene();
  SelfCollision sc(s.tris, s.rest, static_cast<int>(state.range(0)));
  std::vector<Contact> out;
  CollisionStats st;
  for (auto _ : state) {
    sc.detect(s.x0, s.x1, kGap, out, &st);
    benchmark::DoNotOptimize(out.data());
  }
  set_counters(state, st);
}
BENCHMARK(BM_SelfCollisionBvh)->Arg(6)->Arg(14)->Arg(18)->Arg(26)->Unit(benchmark::kMillisecond);

// The same frame with all pairs of triangle k-DOPs (the paper's way).
void BM_SelfCollisionAllPairs(benchmark::State& state) {
  const BvhScene s = make_bvh_scene();
  SelfCollision sc(s.tris, s.rest, static_cast<int>(state.range(0)));
  std::vector<Contact> out;
  CollisionStats st;
  for (auto _ : state) {
    sc.detect_brute_force(s.x0, s.x1, kGap, out, &st);
    benchmark::DoNotOptimize(out.data());
  }
  set_counters(state, st);
}
BENCHMARK(BM_SelfCollisionAllPairs)->Arg(6)->Arg(14)->Arg(18)->Arg(26)->Unit(benchmark::kMillisecond);

// Broad phase alone on the same frame: swept leaf k-DOPs, then overlapping triangle pairs by BVH refit +
// self-traversal (BroadPhaseBvh) or by all pairs (BroadPhaseAllPairs).
template <int K>
std::vector<lumen::collision::Kdop<K>> swept_boxes(const BvhScene& s) {
  std::vector<lumen::collision::Kdop<K>> boxes(static_cast<std::size_t>(s.tris.rows()));
  for (int t = 0; t < s.tris.rows(); ++t) {
    auto& b = boxes[static_cast<std::size_t>(t)];
    b.clear();
    for (int j = 0; j < 3; ++j) {
      b.add_point(s.x0.data() + 3 * s.tris(t, j));
      b.add_point(s.x1.data() + 3 * s.tris(t, j));
    }
    b.inflate(kGap);
  }
  return boxes;
}

template <int K>
void BM_BroadPhaseBvh(benchmark::State& state) {
  const BvhScene s = make_bvh_scene();
  const int n = static_cast<int>(s.tris.rows());
  std::vector<double> centres(static_cast<std::size_t>(3 * n));
  for (int t = 0; t < n; ++t) {
    for (int d = 0; d < 3; ++d) {
      centres[static_cast<std::size_t>(3 * t + d)] =
          (s.rest(s.tris(t, 0), d) + s.rest(s.tris(t, 1), d) + s.rest(s.tris(t, 2), d)) / 3.0;
    }
  }
  lumen::collision::KdopBvh<K> bvh;
  bvh.build(centres.data(), n);
  long pairs = 0;
  for (auto _ : state) {
    const auto boxes = swept_boxes<K>(s);
    for (int t = 0; t < n; ++t) bvh.leaf_box(t) = boxes[static_cast<std::size_t>(t)];
    bvh.refit();
    pairs = 0;
    bvh.self_pairs([&pairs](int, int) { ++pairs; });
    benchmark::DoNotOptimize(pairs);
  }
  state.counters["bv_overlaps"] = static_cast<double>(pairs);
}
BENCHMARK_TEMPLATE(BM_BroadPhaseBvh, 6)->Unit(benchmark::kMicrosecond);
BENCHMARK_TEMPLATE(BM_BroadPhaseBvh, 14)->Unit(benchmark::kMicrosecond);
BENCHMARK_TEMPLATE(BM_BroadPhaseBvh, 18)->Unit(benchmark::kMicrosecond);
BENCHMARK_TEMPLATE(BM_BroadPhaseBvh, 26)->Unit(benchmark::kMicrosecond);

template <int K>
void BM_BroadPhaseAllPairs(benchmark::State& state) {
  const BvhScene s = make_bvh_scene();
  const std::size_t n = static_cast<std::size_t>(s.tris.rows());
  long pairs = 0;
  for (auto _ : state) {
    const auto boxes = swept_boxes<K>(s);
    pairs = 0;
    for (std::size_t a = 0; a < n; ++a) {
      for (std::size_t b = a + 1; b < n; ++b) pairs += boxes[a].overlaps(boxes[b]);
    }
    benchmark::DoNotOptimize(pairs);
  }
  state.counters["bv_overlaps"] = static_cast<double>(pairs);
}
BENCHMARK_TEMPLATE(BM_BroadPhaseAllPairs, 6)->Unit(benchmark::kMicrosecond);
BENCHMARK_TEMPLATE(BM_BroadPhaseAllPairs, 14)->Unit(benchmark::kMicrosecond);
BENCHMARK_TEMPLATE(BM_BroadPhaseAllPairs, 18)->Unit(benchmark::kMicrosecond);
BENCHMARK_TEMPLATE(BM_BroadPhaseAllPairs, 26)->Unit(benchmark::kMicrosecond);

// Exact discrete intersection count (run on every frame by the engine): 0 = the rest tube (prismatic:
// many exactly coplanar neighbours), 1 = the frame's start (walls 10 % apart), 2 = its end (walls touching).
void BM_CountIntersectingPairs(benchmark::State& state) {
  const BvhScene s = make_bvh_scene();
  const Points& x = state.range(0) == 0 ? s.rest : (state.range(0) == 1 ? s.x0 : s.x1);
  long n = 0;
  for (auto _ : state) {
    n = lumen::collision::count_intersecting_pairs(x, s.tris);
    benchmark::DoNotOptimize(n);
  }
  state.counters["intersecting_pairs"] = static_cast<double>(n);
}
BENCHMARK(BM_CountIntersectingPairs)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMicrosecond);

}  // namespace
