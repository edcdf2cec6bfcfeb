// Contact response: contact_row against the separation it constrains (direct and finite differences), and
// whole sessions of a small squeezed tube checked by the exact intersection count. (The LCP solver and
// solve_contacts unit tests are in tests/physics/test_lcp.cpp and tests/physics/test_contact_solve.cpp.)
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>
#include <memory>
#include <random>
#include <stdexcept>
#include <vector>

#include "collision/distance.hpp"
#include "collision/self_collision.hpp"
#include "engine/instrument_contact.hpp"
#include "engine/response.hpp"
#include "engine/scene.hpp"
#include "engine/session.hpp"
#include "engine/simulation.hpp"
#include "physics/compliance.hpp"
#include "physics/fem.hpp"
#include "physics/mesh.hpp"
#include "support/scene_files.hpp"

namespace lumen::engine {
namespace {

using physics::ContactRow;

// ---------------------------------------------------------------------------------------------------------------
// contact_row

// The separation vector of a contact from its definition: vf p - ((1-s-t) a + s b + t c); ee the point at s on
// ab minus the point at t on cd.
Eigen::Vector3d separation(const collision::Contact& c, const Points& x) {
  auto p = [&](int k) -> Eigen::Vector3d { return x.row(c.v[k]).transpose(); };
  if (c.kind == collision::FeatureKind::VertexFace) return p(0) - ((1 - c.s - c.t) * p(1) + c.s * p(2) + c.t * p(3));
  return ((1 - c.s) * p(0) + c.s * p(1)) - ((1 - c.t) * p(2) + c.t * p(3));
}

Points at_time(const Points& x0, const Points& x1, double tau) { return (1 - tau) * x0 + tau * x1; }

// The row is the separation along n: H u - g = n . d(rest + u) - gap for every u; n is the unit separation
// direction at the time of contact, and H is the gradient of the separation distance there (central finite
// differences of |d|).
TEST(ContactRow, IsTheSeparationAlongTheNormal) {
  std::mt19937 rng(24);
  std::normal_distribution<double> nd(0.0, 0.01);
  std::uniform_real_distribution<double> u01(0.05, 0.9);
  const double gap = 1e-4;
  for (int trial = 0; trial < 40; ++trial) {
    Points rest(6, 3), x0(6, 3), x1(6, 3);
    for (int i = 0; i < rest.size(); ++i) rest.data()[i] = nd(rng), x0.data()[i] = nd(rng), x1.data()[i] = nd(rng);
    collision::Contact c;
    c.kind = trial % 2 ? collision::FeatureKind::EdgeEdge : collision::FeatureKind::VertexFace;
    c.v[0] = 4, c.v[1] = 0, c.v[2] = 5, c.v[3] = 2;
    c.toi = u01(rng);
    c.s = 0.5 * u01(rng), c.t = 0.5 * u01(rng);
    const ContactRow row = contact_row(c, rest, x0, x1, gap);
    const Eigen::Vector3d d_toi = separation(c, at_time(x0, x1, c.toi));
    EXPECT_NEAR(row.n.norm(), 1.0, 1e-14);
    EXPECT_LE((row.n - d_toi.normalized()).norm(), 1e-12);
    for (int k = 0; k < 3; ++k) {
      Eigen::VectorXd u(18);
      for (int i = 0; i < 18; ++i) u[i] = nd(rng);
      const Points x = rest + Eigen::Map<const Points>(u.data(), 6, 3);
      EXPECT_NEAR(physics::row_values({row}, u)[0] - row.g, row.n.dot(separation(c, x)) - gap, 1e-15);
    }
    // Gradient of |d| at the time of contact along random nodal directions.
    const Points xt = at_time(x0, x1, c.toi);
    Eigen::VectorXd du(18);
    for (int i = 0; i < 18; ++i) du[i] = nd(rng);
    const Points dx = Eigen::Map<const Points>(du.data(), 6, 3);
    const double eps = 1e-6;
    const double fd = (separation(c, xt + eps * dx).norm() - separation(c, xt - eps * dx).norm()) / (2 * eps);
    EXPECT_NEAR(physics::row_values({row}, du)[0], fd, 1e-7 * du.norm());
  }
}

// Touching features (zero separation at the time of contact): n is the face normal (vf) or the edges' common
// normal (ee), pointing to the side the first feature came from; the row is still the separation along n.
TEST(ContactRow, TouchingFeaturesUseTheGeometricNormal) {
  std::mt19937 rng(25);
  std::normal_distribution<double> nd(0.0, 0.01);
  std::uniform_real_distribution<double> u01(0.1, 0.8);
  for (int trial = 0; trial < 20; ++trial) {
    collision::Contact c;
    c.kind = trial % 2 ? collision::FeatureKind::EdgeEdge : collision::FeatureKind::VertexFace;
    c.v[0] = 0, c.v[1] = 1, c.v[2] = 2, c.v[3] = 3;
    c.toi = u01(rng), c.s = 0.4 * u01(rng), c.t = 0.4 * u01(rng);
    // Positions at the time of contact with the features touching, the start anywhere; the end follows.
    Points rest(4, 3), x0(4, 3), xt(4, 3);
    for (int i = 0; i < 12; ++i) rest.data()[i] = nd(rng), x0.data()[i] = nd(rng), xt.data()[i] = nd(rng);
    if (c.kind == collision::FeatureKind::VertexFace) {
      xt.row(0) = (1 - c.s - c.t) * xt.row(1) + c.s * xt.row(2) + c.t * xt.row(3);
    } else {
      // Move the second edge so that its point at t meets the first edge's point at s.
      const Eigen::RowVector3d shift = ((1 - c.s) * xt.row(0) + c.s * xt.row(1)) - ((1 - c.t) * xt.row(2) + c.t * xt.row(3));
      xt.row(2) += shift, xt.row(3) += shift;
    }
    const Points x1 = x0 + (xt - x0) / c.toi;
    ASSERT_LE(separation(c, at_time(x0, x1, c.toi)).norm(), 1e-12);
    const ContactRow row = contact_row(c, rest, x0, x1, 1e-4);
    EXPECT_NEAR(row.n.norm(), 1.0, 1e-12);
    const Points xc = at_time(x0, x1, c.toi);
    const Eigen::Vector3d e1 = c.kind == collision::FeatureKind::VertexFace ? Eigen::Vector3d(xc.row(2) - xc.row(1))
                                                                            : Eigen::Vector3d(xc.row(1) - xc.row(0));
    const Eigen::Vector3d e2 = c.kind == collision::FeatureKind::VertexFace ? Eigen::Vector3d(xc.row(3) - xc.row(1))
                                                                            : Eigen::Vector3d(xc.row(3) - xc.row(2));
    EXPECT_LE(std::abs(row.n.dot(e1)), 1e-9 * e1.norm());
    EXPECT_LE(std::abs(row.n.dot(e2)), 1e-9 * e2.norm());
    EXPECT_GE(row.n.dot(separation(c, x0)), 0.0);
    Eigen::VectorXd u(12);
    for (int i = 0; i < 12; ++i) u[i] = nd(rng);
    const Points x = rest + Eigen::Map<const Points>(u.data(), 4, 3);
    EXPECT_NEAR(physics::row_values({row}, u)[0] - row.g, row.n.dot(separation(c, x)) - 1e-4, 1e-15);
  }
}

// Four points' feature distance by the library's closest-point code: vertex 0 to triangle 123, or segment 01 to
// segment 23, metres.
double feature_distance(collision::FeatureKind kind, const Points& x) {
  auto p = [&](int k) -> Eigen::Vector3d { return x.row(k).transpose(); };
  return kind == collision::FeatureKind::VertexFace ? collision::point_triangle_distance(p(0), p(1), p(2), p(3))
                                                    : collision::segment_segment_distance(p(0), p(1), p(2), p(3));
}

// A row's value H u at positions x of four nodes whose rest positions are 0 (so u = x), metres.
double row_value_at(const ContactRow& row, const Points& x) {
  return physics::row_values({row}, Eigen::Map<const Eigen::VectorXd>(x.data(), x.size()))[0];
}

// A contact held from the last frame, re-measured where its four features' points are now (x, rest 0): its row's
// value is the brute-force distance (to `spacing`), and its gradient (weights times normal) the distance's, by
// central finite differences.
void expect_remeasured_row_is_the_distance(const collision::Contact& found, const Points& x, double brute,
                                           double spacing) {
  State state;
  state.x = x;
  const HeldContact h = remeasured(HeldContact{found, -1, 0}, state);
  EXPECT_EQ(h.c.toi, 0.0);
  const ContactRow row = contact_row(h.c, Points::Zero(4, 3), x, x, 1e-4);
  EXPECT_NEAR(row_value_at(row, x), brute, spacing);
  const double h_step = 1e-7;
  for (int k = 0; k < 4; ++k)
    for (int a = 0; a < 3; ++a) {
      Points xp = x, xm = x;
      xp(k, a) += h_step;
      xm(k, a) -= h_step;
      const double fd = (feature_distance(found.kind, xp) - feature_distance(found.kind, xm)) / (2 * h_step);
      EXPECT_NEAR(row.weight[k] * row.n[a], fd, 1e-6) << "vertex " << k << " axis " << a;
    }
}

// Vertex-face: after the vertex slid 0.7 mm along the face (and the face tilted), the re-measured row is the
// distance to the face's closest point now; the contact as found (its old barycentric point) is off by a fraction
// of a millimetre (the check can fail). Truth: the closest of 400 x 400 barycentric samples.
TEST(ContactRow, AHeldSelfContactIsReMeasuredWhereItsFeaturesAreNow) {
  Points x(4, 3);
  x << 0.0012, 0.0007, 0.0001,   // vertex, 0.1 mm above the face and slid 0.7 mm along it
      0.0, 0.0, 0.0, 0.002, 0.0, 0.00002, 0.0, 0.002, -0.00001;
  const collision::Contact found{collision::FeatureKind::VertexFace, {0, 1, 2, 3}, 0.4, 0.2, 0.1};
  double brute = 1e300;
  const int m = 400;
  for (int i = 0; i <= m; ++i)
    for (int j = 0; i + j <= m; ++j) {
      const double b = double(i) / m, c = double(j) / m;
      const Eigen::Vector3d q = ((1 - b - c) * x.row(1) + b * x.row(2) + c * x.row(3)).transpose();
      brute = std::min(brute, (x.row(0).transpose() - q).norm());
    }
  expect_remeasured_row_is_the_distance(found, x, brute, 0.002 / m);
  const ContactRow stale = contact_row(found, Points::Zero(4, 3), x, x, 1e-4);
  EXPECT_GT(std::abs(row_value_at(stale, x) - brute), 1e-4);
}

// Edge-edge: after the edges slid along each other. Truth: the closest of 1000 x 1000 pairs of their parameters.
TEST(ContactRow, AHeldEdgeEdgeContactIsReMeasuredWhereItsFeaturesAreNow) {
  Points x(4, 3);
  x << 0.0, 0.0, 0.0, 0.002, 0.0002, 0.0,   // edge ab along x
      0.0013, -0.0009, 0.00011, 0.0007, 0.0011, 0.00012;  // edge cd across it, 0.1 mm above
  const collision::Contact found{collision::FeatureKind::EdgeEdge, {0, 1, 2, 3}, 0.3, 0.15, 0.8};
  double brute = 1e300;
  const int m = 1000;
  for (int i = 0; i <= m; ++i)
    for (int j = 0; j <= m; ++j) {
      const double a = double(i) / m, b = double(j) / m;
      const Eigen::Vector3d p = ((1 - a) * x.row(0) + a * x.row(1)).transpose();
      const Eigen::Vector3d q = ((1 - b) * x.row(2) + b * x.row(3)).transpose();
      brute = std::min(brute, (p - q).norm());
    }
  expect_remeasured_row_is_the_distance(found, x, brute, 0.0025 / m);
}

// ---------------------------------------------------------------------------------------------------------------
// Whole sessions: a coarse tube squeezed shut by two opposite probes; with either response the inner wall never
// intersects (exact check, independent of the CCD code), and the walls really meet.

Scene squeeze_scene(const std::string& response, int frames) {
  Scene s = load_scene(std::string(LUMEN_SOURCE_DIR) + "/scenes/full-closure.json");
  s.mesh.segments_around = 12;
  s.mesh.segments_along = 8;
  s.mesh.layers = 2;
  s.mesh.length = 0.06;
  for (ProbeSpec& p : s.probes) {
    p.point.z() = 0.03;
    p.track = {TrackKey{0.0, Eigen::Vector3d::Zero()}, TrackKey{0.5, 3.0 * p.track.back().value},
               TrackKey{1.0, 3.0 * p.track.back().value}};
  }
  s.frames = frames;
  s.collision.response = response == "paper" ? ResponseKind::kPaper : ResponseKind::kConstraint;
  return s;
}

void expect_session_intersection_free(const std::string& response, int frames) {
  const SessionResult r = lumen::test::run_checked_session(squeeze_scene(response, frames));
  long contacts = 0, solved_frames = 0;
  for (const FrameRecord& f : r.frames) {
    EXPECT_EQ(f.intersecting_pairs, 0) << response << " frame " << f.frame;
    EXPECT_FALSE(f.numerical_failure) << response << " frame " << f.frame;
    contacts += f.contacts;
    solved_frames += f.response_iterations > 0 && !f.fallback;
  }
  EXPECT_GT(contacts, 0) << response;
  EXPECT_GT(solved_frames, 0) << response;
}

TEST(CollideAndRespond, ConstraintResponseKeepsTheSqueezedTubeIntersectionFree) {
  expect_session_intersection_free("constraint", 36);
}

// The paper's hold resolves the first contact frames and then needs the safe fallback once the closure spreads
// (every round re-checks by CCD, so a short session keeps the test quick).
TEST(CollideAndRespond, PaperResponseKeepsTheSqueezedTubeIntersectionFree) {
  expect_session_intersection_free("paper", 14);
}

// A frame whose contacts exceed collision.max_contact_rows stops short (the safe fallback) and keeps no contact,
// but its correction (the stop) is carried as the next frame's prediction. Under a force applied at once and held,
// the first frame's motion crosses the closure and is capped; the second frame's prediction is where the first
// stopped, meets nothing, and the frame ends on its free motion, which crosses the closure again: the check must
// run on that motion, not on the prediction (it did not, and the walls passed through each other).
TEST(CollideAndRespond, AFrameAfterACappedFallbackChecksTheMotionItCommits) {
  Scene s = squeeze_scene("constraint", 6);
  for (ProbeSpec& p : s.probes) {
    const Eigen::Vector3d held = p.track.back().value;
    p.track = {TrackKey{0.0, held}, TrackKey{1.0, held}};
  }
  s.collision.max_contact_rows = 4;
  const SessionResult r = lumen::test::run_checked_session(s);
  ASSERT_TRUE(r.frames.front().contact_rows_capped) << "the first frame should cross the closure with many contacts";
  for (const FrameRecord& f : r.frames) {
    EXPECT_EQ(f.intersecting_pairs, 0) << "frame " << f.frame;
    EXPECT_TRUE(f.contact_rows_capped) << "frame " << f.frame << ": its free motion crosses the closure again";
  }
}

// Without any response the same squeeze makes the walls pass through each other (the scene tests something).
TEST(CollideAndRespond, TheSqueezeIntersectsWithoutResponse) {
  Scene s = squeeze_scene("constraint", 36);
  s.collision.self = false;
  const SessionResult r = lumen::test::run_checked_session(s);
  long frames_with = 0;
  for (const FrameRecord& f : r.frames) frames_with += f.intersecting_pairs > 0;
  EXPECT_GT(frames_with, 3);
}

// A quasi-static linear tube held shut under a constant load has one equilibrium: once the load stops changing,
// the frames must come to rest (every node still) with one response round each. 13,392 tets, seven 3 mm-apart
// probes a side at 0.1 N a side, ramped over a second and held. Carried contacts measured at their old closest
// points kept it from resting (the probes moved 3-70 micrometres a frame, every few frames two rounds).
TEST(CollideAndRespond, AConstantSqueezeComesToRest) {
  Scene s = load_scene(std::string(LUMEN_SOURCE_DIR) + "/scenes/full-closure.json");
  s.mesh.segments_around = 24;
  s.mesh.segments_along = 31;
  s.mesh.layers = 3;
  const double facet = 2.0 * M_PI / s.mesh.segments_around;
  const double r = s.mesh.outer_radius * 0.5 * (1.0 + std::cos(0.5 * facet));  // between a facet and its corners
  const double tip = 0.003, side_force = 0.1;
  s.probes.clear();
  for (const double sign : {1.0, -1.0})
    for (int k = 0; k < 7; ++k) {
      const double arc = k == 0 ? 0.0 : tip * std::cos(M_PI / 3 * (k - 1));
      const double dz = k == 0 ? 0.0 : tip * std::sin(M_PI / 3 * (k - 1));
      const double a = M_PI / 2 - arc / r;
      ProbeSpec p;
      p.point = Eigen::Vector3d(r * std::cos(a), sign * r * std::sin(a), 0.5 * s.mesh.length + dz);
      const Eigen::Vector3d f(0.0, -sign * side_force / 7, 0.0);
      p.track = {TrackKey{0.0, Eigen::Vector3d::Zero()}, TrackKey{1.0, f}, TrackKey{1000.0, f}};
      s.probes.push_back(p);
    }
  s.frames = 120;
  const auto model = compile_model(s);
  Inputs inputs = make_inputs(s);
  State state = make_state(*model);
  double last_move = 0.0;
  int contact_frames = 0;
  for (int i = 0; i < s.frames; ++i) {
    const Points before = state.x;
    FrameRecord rec;
    step(*model, inputs, state, rec);
    contact_frames += rec.response_iterations > 0;
    if (i < s.frames - 20) continue;
    const double move = (state.x - before).rowwise().norm().maxCoeff();
    EXPECT_EQ(rec.response_iterations, 1) << "frame " << i + 1;
    EXPECT_FALSE(rec.fallback) << "frame " << i + 1;
    EXPECT_LT(move, 1e-3 * s.collision.gap) << "frame " << i + 1 << ": a node moved " << move << " m";
    last_move = move;
  }
  EXPECT_GT(contact_frames, 60) << "the walls must meet and stay shut";
  std::printf("constant squeeze: last frame's largest node move %.3g m (gap %.3g m)\n", last_move, s.collision.gap);
}

// ---------------------------------------------------------------------------------------------------------------
// The deferred interior (State::defer_interior): a contact frame's whole-mesh correction exact on the colliding and
// drawn nodes at once, its interior solved on a second thread between step_begin and step_end.

// The squeeze with the compliance's whole-mesh columns refused, so its correction back-substitutes (the path that
// defers, as on large meshes).
std::unique_ptr<Model> deferring_model(const Scene& scene) {
  auto model = compile_model(scene);
  model->compliance_mesh_column_bytes = 0;
  return model;
}

// Against its serial twin (step(), nothing deferred) frame by frame: what step_begin leaves for the renderer is
// already the twin's end state on every node the renderer reads, and after step_end the whole state and record are
// the twin's (to round-off: the interior comes from a solve instead of the rows).
TEST(DeferredInterior, EqualsTheSerialCorrectionFrameByFrame) {
  const Scene scene = squeeze_scene("constraint", 30);
  const auto model = deferring_model(scene);
  Inputs in_deferred = make_inputs(scene), in_serial = make_inputs(scene);
  State deferred = make_state(*model), serial = make_state(*model);
  ASSERT_TRUE(deferred.compliance->keeps_view_rows());
  ASSERT_FALSE(model->view_nodes.empty());
  deferred.defer_interior = true;
  const double scale = 0.01;  // metres: the squeeze's displacements are millimetres
  int deferred_frames = 0;
  for (int i = 0; i < scene.frames; ++i) {
    FrameRecord rd, rs;
    step(*model, in_serial, serial, rs);
    step_begin(*model, in_deferred, deferred, rd);
    FrameRecord again;
    EXPECT_THROW(step_begin(*model, in_deferred, deferred, again), std::logic_error) << "frame " << rd.frame;
    deferred_frames += rd.interior_deferred;
    // What the renderer reads, before the join: the twin's end positions.
    for (int v : model->view_nodes)
      EXPECT_LE((deferred.x.row(v) - serial.x.row(v)).norm(), 1e-12 * scale) << "frame " << rd.frame << " node " << v;
    EXPECT_EQ(deferred.frame, serial.frame);
    step_end(*model, in_deferred, deferred, rd);
    EXPECT_THROW(step_end(*model, in_deferred, deferred, again), std::logic_error) << "frame " << rd.frame;
    EXPECT_LE((deferred.sim.u - serial.sim.u).cwiseAbs().maxCoeff(), 1e-12 * scale) << "frame " << rd.frame;
    EXPECT_LE((deferred.x - serial.x).cwiseAbs().maxCoeff(), 1e-12 * scale) << "frame " << rd.frame;
    EXPECT_LE((deferred.last_correction - serial.last_correction).cwiseAbs().maxCoeff(), 1e-12 * scale);
    EXPECT_EQ(rd.inverted_elements, rs.inverted_elements);
    EXPECT_EQ(rd.numerical_failure, rs.numerical_failure);
    EXPECT_EQ(rd.response_iterations, rs.response_iterations) << "frame " << rd.frame;
    EXPECT_EQ(rd.contacts, rs.contacts) << "frame " << rd.frame;
    EXPECT_NEAR(rd.contact_force, rs.contact_force, 1e-9 * std::max(1.0, rs.contact_force));
    EXPECT_NEAR(rd.max_displacement, rs.max_displacement, 1e-12 * scale);
    ASSERT_EQ(rd.probe_displacement.size(), rs.probe_displacement.size());
    for (size_t p = 0; p < rd.probe_displacement.size(); ++p)
      EXPECT_LE((rd.probe_displacement[p] - rs.probe_displacement[p]).norm(), 1e-12 * scale);
    EXPECT_FALSE(rs.interior_deferred);
  }
  // The squeeze's contact frames deferred (resolved ones; a fallback frame never does).
  EXPECT_GT(deferred_frames, 5);
}

// A rendering session defers (its frames say so) and ends where the same session run serially ends; the kept
// whole-mesh columns (the default budget on this small mesh) sum instead of solving, so nothing defers there.
TEST(DeferredInterior, RenderingSessionEndsWhereTheSerialOneDoes) {
  Scene scene = squeeze_scene("constraint", 24);
  scene.render.width = 160;
  scene.render.height = 120;
  const auto model = deferring_model(scene);
  auto run = [&](const Model& m, bool overlap, Points& last) {
    SessionOptions opt;
    opt.render = true;
    opt.write_frames = false;
    opt.overlap_interior = overlap;
    opt.on_frame = [&](const Model&, const State& state, const FrameRecord&) { last = state.x; };
    return run_session(m, make_inputs(scene), opt);
  };
  Points overlapped, serial, kept;
  const SessionResult a = run(*model, true, overlapped), b = run(*model, false, serial);
  long deferred = 0;
  for (const FrameRecord& f : a.frames) deferred += f.interior_deferred;
  for (const FrameRecord& f : b.frames) EXPECT_FALSE(f.interior_deferred);
  EXPECT_GT(deferred, 5);
  EXPECT_LE((overlapped - serial).cwiseAbs().maxCoeff(), 1e-14);
  const auto default_model = compile_model(scene);
  const SessionResult c = run(*default_model, true, kept);
  for (const FrameRecord& f : c.frames) EXPECT_FALSE(f.interior_deferred) << "frame " << f.frame;
  EXPECT_LE((kept - serial).cwiseAbs().maxCoeff(), 1e-14);
}

// A pipelined interior (State::pipeline_interior: solved on until the next frame's response is done) against the
// same session whose frames each wait for their own (pipeline_interior off) and against the serial one: the
// records, field by field, and the committed end state are the in-frame twin's to the last bit (the same solves in
// the same order, only joined later) and the serial one's to round-off. A contact-row cap of 30 makes frames
// fall back right after deferred ones, whose first trial motion is still the prediction (the path that must take
// the last correction's interior, whole only after the settle).
void expect_pipelined_equals_in_frame(int max_contact_rows, bool expect_fallback_after_deferral) {
  Scene scene = squeeze_scene("constraint", 30);
  scene.render.width = 160;
  scene.render.height = 120;
  scene.collision.max_contact_rows = max_contact_rows;
  const auto model = deferring_model(scene);
  struct End {
    Points x;
    Eigen::VectorXd u, last_correction;
    bool pipelined = false;
  };
  auto run = [&](bool overlap, bool pipeline, End& end) {
    SessionOptions opt;
    opt.render = true;
    opt.write_frames = false;
    opt.overlap_interior = overlap;
    opt.pipeline_interior = pipeline;
    opt.on_end = [&](const Model&, const State& state, const FrameRecord&) {
      end = End{state.x, state.sim.u, state.last_correction, state.pipeline_interior};
    };
    return run_session(*model, make_inputs(scene), opt);
  };
  End piped, in_frame, serial;
  const SessionResult a = run(true, true, piped), b = run(true, false, in_frame), c = run(false, false, serial);
  EXPECT_TRUE(piped.pipelined);
  EXPECT_FALSE(in_frame.pipelined);
  ASSERT_EQ(a.frames.size(), b.frames.size());
  ASSERT_EQ(a.frames.size(), c.frames.size());
  long deferred = 0, fallback_after_deferral = 0;
  for (size_t i = 0; i < a.frames.size(); ++i) {
    const FrameRecord &ra = a.frames[i], &rb = b.frames[i];
    deferred += ra.interior_deferred;
    fallback_after_deferral += i > 0 && a.frames[i - 1].interior_deferred && ra.fallback;
    EXPECT_EQ(ra.frame, rb.frame);
    EXPECT_EQ(ra.interior_deferred, rb.interior_deferred) << "frame " << ra.frame;
    EXPECT_EQ(ra.contacts, rb.contacts) << "frame " << ra.frame;
    EXPECT_EQ(ra.first_contacts, rb.first_contacts) << "frame " << ra.frame;
    EXPECT_EQ(ra.bv_overlaps, rb.bv_overlaps) << "frame " << ra.frame;
    EXPECT_EQ(ra.response_iterations, rb.response_iterations) << "frame " << ra.frame;
    EXPECT_EQ(ra.fallback, rb.fallback) << "frame " << ra.frame;
    EXPECT_EQ(ra.contact_rows_capped, rb.contact_rows_capped) << "frame " << ra.frame;
    EXPECT_EQ(ra.fallback_kept, rb.fallback_kept) << "frame " << ra.frame;
    EXPECT_EQ(ra.contact_force, rb.contact_force) << "frame " << ra.frame;
    EXPECT_EQ(ra.inverted_elements, rb.inverted_elements) << "frame " << ra.frame;
    EXPECT_EQ(ra.numerical_failure, rb.numerical_failure) << "frame " << ra.frame;
    EXPECT_EQ(ra.max_displacement, rb.max_displacement) << "frame " << ra.frame;
    EXPECT_GT(ra.max_displacement, 0.0) << "frame " << ra.frame << ": its commit fields were never filed";
    ASSERT_EQ(ra.probe_displacement.size(), rb.probe_displacement.size());
    for (size_t p = 0; p < ra.probe_displacement.size(); ++p)
      EXPECT_EQ(ra.probe_displacement[p], rb.probe_displacement[p]) << "frame " << ra.frame << " probe " << p;
    ASSERT_EQ(ra.reactions.size(), rb.reactions.size());
    for (size_t p = 0; p < ra.reactions.size(); ++p) EXPECT_EQ(ra.reactions[p], rb.reactions[p]);
    EXPECT_EQ(ra.fallback, c.frames[i].fallback) << "frame " << ra.frame;
    EXPECT_EQ(ra.contacts, c.frames[i].contacts) << "frame " << ra.frame;
  }
  EXPECT_GT(deferred, 5);
  if (expect_fallback_after_deferral) {
    EXPECT_GT(fallback_after_deferral, 0);
  }
  EXPECT_EQ((piped.x - in_frame.x).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ((piped.u - in_frame.u).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ((piped.last_correction - in_frame.last_correction).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_LE((piped.x - serial.x).cwiseAbs().maxCoeff(), 1e-14);
}

TEST(PipelinedInterior, SessionEqualsTheOneThatWaitsEveryFrame) {
  expect_pipelined_equals_in_frame(kDefaultMaxContactRows, false);
}
TEST(PipelinedInterior, FallbackRightAfterADeferredFrameEqualsTheOneThatWaits) {
  expect_pipelined_equals_in_frame(30, true);
}

}  // namespace
}  // namespace lumen::engine
