// Test support for instrument sessions (for test programs that link the engine): checks of tool-organ contact
// that are independent of the contact code: signed distances by brute force over collision/distance.hpp, inside
// tests by ray parity, and the organ's elastic force K u from an independently assembled stiffness.
#pragma once

#include <cmath>
#include <limits>

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <nlohmann/json.hpp>

#include "collision/distance.hpp"
#include "engine/session.hpp"
#include "engine/simulation.hpp"
#include "physics/fem.hpp"

namespace lumen::test {

using engine::Model;
using engine::State;

// The organ's closed boundary: outer wall, inner wall and end caps (none on a closed wall: a grown surface, a pair).
inline Tris organ_boundary(const Model& m) {
  const Tris& outer = m.outer_wall();
  const Tris& inner = m.inner_wall();
  const physics::MeshSurface* caps = physics::find_named(m.mesh.surfaces, physics::kEndCaps);
  const Tris ends = caps ? caps->tris : Tris(0, 3);
  Tris all(outer.rows() + inner.rows() + ends.rows(), 3);
  all << outer, inner, ends;
  return all;
}

// Whether p is inside the closed surface (x, tris): parity of the crossings of a ray in a direction no mesh here
// is aligned with (Moller-Trumbore, hits at positive distance along the ray).
inline bool inside_closed(const Points& x, const Tris& tris, const Eigen::Vector3d& p) {
  const Eigen::Vector3d dir = Eigen::Vector3d(0.5773, 0.6211, 0.5303).normalized();
  constexpr double kParallel = 1e-18;
  int crossings = 0;
  for (int t = 0; t < tris.rows(); ++t) {
    const Eigen::Vector3d a = x.row(tris(t, 0)), b = x.row(tris(t, 1)), c = x.row(tris(t, 2));
    const Eigen::Vector3d e1 = b - a, e2 = c - a, h = dir.cross(e2);
    const double det = e1.dot(h);
    if (std::abs(det) < kParallel) continue;
    const Eigen::Vector3d s = p - a;
    const double u = s.dot(h) / det;
    const Eigen::Vector3d q = s.cross(e1);
    const double v = dir.dot(q) / det;
    const double along = e2.dot(q) / det;
    crossings += u >= 0.0 && v >= 0.0 && u + v <= 1.0 && along > 0.0;
  }
  return crossings % 2 == 1;
}

// Distance from p to the surface (x, tris) by brute force over its triangles, negative inside it. A triangle whose
// bounding box is farther from p than the nearest triangle so far is skipped: the distance to a triangle is never
// less than the distance to its box, so the minimum is exact.
inline double signed_distance(const Points& x, const Tris& tris, const Eigen::Vector3d& p) {
  double d = std::numeric_limits<double>::infinity();
  for (int t = 0; t < tris.rows(); ++t) {
    const Eigen::Vector3d a = x.row(tris(t, 0)), b = x.row(tris(t, 1)), c = x.row(tris(t, 2));
    const Eigen::Vector3d lo = a.cwiseMin(b).cwiseMin(c), hi = a.cwiseMax(b).cwiseMax(c);
    if ((lo - p).cwiseMax(p - hi).cwiseMax(0.0).norm() >= d) continue;
    d = std::min(d, collision::point_triangle_distance(p, a, b, c));
  }
  return inside_closed(x, tris, p) ? -d : d;
}

// How clear the instruments are of the organ at the end of a frame: the smallest signed distance of a tool
// vertex to the organ's boundary, and the number of organ boundary nodes inside a tool part.
struct ToolClearance {
  double min_tool_vertex = std::numeric_limits<double>::infinity();  // metres
  int organ_nodes_inside_tool = 0;
};
inline ToolClearance tool_clearance(const Model& m, const State& s) {
  ToolClearance c;
  const Tris boundary = organ_boundary(m);
  for (size_t p = 0; p < m.tool_parts.size(); ++p) {
    const engine::ToolPart& tp = m.tool_parts[p];
    const Tris& tool_tris = m.instruments[tp.instrument].instrument.parts[tp.part].mesh.tris;
    const Points& y = s.tool_points[p];
    for (int i = 0; i < y.rows(); ++i)
      c.min_tool_vertex = std::min(c.min_tool_vertex, signed_distance(s.x, boundary, y.row(i).transpose()));
    // Organ nodes inside the part's box, then by parity.
    const Eigen::Vector3d lo = y.colwise().minCoeff(), hi = y.colwise().maxCoeff();
    for (int t = 0; t < boundary.size(); ++t) {
      const Eigen::Vector3d q = s.x.row(boundary.data()[t]);
      if ((q.array() >= lo.array()).all() && (q.array() <= hi.array()).all() && inside_closed(y, tool_tris, q))
        ++c.organ_nodes_inside_tool;
    }
  }
  return c;
}

// The organ's elastic nodal forces K u at the committed state (K: the linear tet4 stiffness, assembled by the caller
// from the mesh and the material with physics::assemble_stiffness), summed over the nodes that are not fixed: with
// no other load, the total force the instruments put on the organ. torque: their moment about `point`.
struct ElasticLoad {
  Eigen::Vector3d force = Eigen::Vector3d::Zero();
  Eigen::Vector3d torque = Eigen::Vector3d::Zero();
};
inline ElasticLoad elastic_load(const Model& m, const State& s, const Eigen::SparseMatrix<double>& K,
                                const Eigen::Vector3d& point) {
  const Eigen::VectorXd f = K * s.sim.u;
  std::vector<bool> fixed(static_cast<size_t>(m.mesh.n_nodes()), false);
  for (int v : m.fixed_nodes) fixed[static_cast<size_t>(v)] = true;
  ElasticLoad load;
  for (int v = 0; v < m.mesh.n_nodes(); ++v) {
    if (fixed[static_cast<size_t>(v)]) continue;
    const Eigen::Vector3d fv = f.segment<3>(3 * v);
    load.force += fv;
    load.torque += (s.x.row(v).transpose() - point).cross(fv);
  }
  return load;
}

// A small tube (the paper's radii and length, 12 x 10 x 2 cells, linear, ends fixed, 40 fps) without probes or
// instruments, for a test to add them.
inline nlohmann::json small_tube_scene(const std::string& name) {
  nlohmann::json s = nlohmann::json::parse(R"({
    "mesh": {"type": "hollow_cylinder", "inner_radius": 0.01, "outer_radius": 0.013, "length": 0.1,
             "segments_around": 12, "segments_along": 10, "layers": 2},
    "material": {"model": "linear", "young_modulus": 5000.0, "poisson_ratio": 0.45},
    "fixed": ["ends"], "probes": [], "fps": 40
  })");
  s["name"] = name;
  return s;
}

// The small tube with self-collision and one instrument of that shape driven by device `device`, its device origin
// at `origin` (metres, organ frame; to_organ a translation), for `frames` frames.
inline nlohmann::json device_tube_scene(const std::string& name, int frames, const nlohmann::json& instrument_shape,
                                        const std::string& device, const Eigen::Vector3d& origin) {
  nlohmann::json s = small_tube_scene(name);
  s["frames"] = frames;
  s["collision"] = {{"self", true}};
  s["instruments"] = {{{"name", name},
                       {"shape", instrument_shape},
                       {"device_name", device},
                       {"to_organ", {1, 0, 0, origin.x(), 0, 1, 0, origin.y(), 0, 0, 1, origin.z(), 0, 0, 0, 1}}}};
  return s;
}

// A session without rendering, with the exact check, measured after every frame: the instruments' clearance, the
// organ's elastic load about the first instrument's origin, and the last frame's positions.
struct CheckedRun {
  std::unique_ptr<Model> model;
  engine::SessionResult result;
  std::vector<ToolClearance> clearance;  // per frame
  std::vector<ElasticLoad> elastic;      // per frame
  std::vector<Points> x;                 // per frame, the organ's positions at its end
  Points final_x;
};
inline CheckedRun run_checked(const engine::Scene& scene) {
  CheckedRun c;
  c.model = engine::compile_model(scene);
  physics::LinearMaterial material;
  material.young_modulus = scene.material.young_modulus;
  material.poisson_ratio = scene.material.poisson_ratio;
  // Assembled once: the mesh never changes.
  const Eigen::SparseMatrix<double> K = physics::assemble_stiffness(c.model->mesh, material);
  engine::SessionOptions opt;
  opt.render = false;
  opt.check = true;
  opt.on_frame = [&](const Model& m, const State& s, const engine::FrameRecord&) {
    c.clearance.push_back(tool_clearance(m, s));
    const Eigen::Vector3d origin = s.tool_pose.empty() ? Eigen::Vector3d::Zero() : s.tool_pose[0].position;
    c.elastic.push_back(elastic_load(m, s, K, origin));
    c.x.push_back(s.x);
    c.final_x = s.x;
  };
  c.result = engine::run_session(*c.model, engine::make_inputs(scene), opt);
  return c;
}

// The checks every frame of a one-instrument session must pass, independent of the contact code: no intersecting
// tool-organ or organ-organ pair by the exact check, no numerical failure, every tool vertex outside the organ by at
// least a quarter of the gap (the re-check clears half of it) and no organ node inside the tool. Returns the
// number of frames the instrument touched the organ.
inline int expect_tool_clear(const CheckedRun& c, double gap) {
  int touching = 0;
  for (size_t i = 0; i < c.result.frames.size(); ++i) {
    const engine::FrameRecord& f = c.result.frames[i];
    EXPECT_EQ(f.instrument_intersecting_pairs, 0) << "frame " << f.frame;
    EXPECT_EQ(f.intersecting_pairs, 0) << "frame " << f.frame;
    EXPECT_FALSE(f.numerical_failure) << "frame " << f.frame;
    EXPECT_GE(c.clearance[i].min_tool_vertex, 0.25 * gap) << "frame " << f.frame;
    EXPECT_EQ(c.clearance[i].organ_nodes_inside_tool, 0) << "frame " << f.frame;
    EXPECT_EQ(f.instruments.size(), 1u) << "frame " << f.frame;
    touching += !f.instruments.empty() && f.instruments[0].contacts > 0;
  }
  return touching;
}

}  // namespace lumen::test
