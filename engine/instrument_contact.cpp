#include "engine/instrument_contact.hpp"

#include <algorithm>
#include <limits>

#include <Eigen/Dense>

#include "collision/distance.hpp"
#include "collision/intersect.hpp"
#include "engine/grasp.hpp"
#include "engine/simulation.hpp"

namespace lumen::engine {
namespace {

// Axis-aligned box of some rows of a point array.
struct Box {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = Eigen::Vector3d::Constant(-std::numeric_limits<double>::infinity());
  void add(const Eigen::Vector3d& p) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  // Closed boxes: touching counts, as it does for the exact triangle test.
  bool overlaps(const Box& o) const { return (lo.array() <= o.hi.array()).all() && (o.lo.array() <= hi.array()).all(); }
};

Box triangle_box(const Points& x, const Tris& tris, int t) {
  Box b;
  for (int k = 0; k < 3; ++k) b.add(x.row(tris(t, k)).transpose());
  return b;
}

// A detect_pair contact (organ = side A, the part = side B) as a held contact of tool part `part`.
HeldContact held_of(const collision::PairContact& pc, int part) {
  HeldContact h;
  h.c.kind = pc.kind;
  std::copy(pc.v, pc.v + 4, h.c.v);
  h.c.toi = pc.toi;
  h.c.s = pc.s;
  h.c.t = pc.t;
  h.part = part;
  for (int k = 0; k < 4; ++k)
    if (pc.side_of(k) == collision::Side::B) h.tool |= 1u << k;
  return h;
}

// The boxes of the organ's wall triangles the instruments touch, at x.
std::vector<Box> organ_boxes(const Model& model, const Points& x) {
  const Tris& organ = model.tool_target_tris;
  std::vector<Box> boxes(static_cast<size_t>(organ.rows()));
  for (int t = 0; t < organ.rows(); ++t) boxes[static_cast<size_t>(t)] = triangle_box(x, organ, t);
  return boxes;
}

// Intersecting (triangle of tool part p at points y, organ wall triangle at x) pairs by the exact test; only the
// organ triangles near the part at all, then the pairs whose boxes meet, are tested.
long part_intersections(const Model& model, const std::vector<Box>& boxes, const Points& x, size_t p, const Points& y) {
  const Tris& organ = model.tool_target_tris;
  const ToolPart& tp = model.tool_parts[p];
  const Tris& tris = model.instruments[tp.instrument].instrument.parts[tp.part].mesh.tris;
  Box part_box;
  for (int i = 0; i < y.rows(); ++i) part_box.add(y.row(i).transpose());
  std::vector<int> near;
  for (int t = 0; t < organ.rows(); ++t)
    if (boxes[static_cast<size_t>(t)].overlaps(part_box)) near.push_back(t);
  long count = 0;
  for (int a = 0; a < tris.rows() && !near.empty(); ++a) {
    const Box box = triangle_box(y, tris, a);
    for (int t : near) {
      if (!box.overlaps(boxes[static_cast<size_t>(t)])) continue;
      count += collision::triangles_intersect(&y(tris(a, 0), 0), &y(tris(a, 1), 0), &y(tris(a, 2), 0),
                                              &x(organ(t, 0), 0), &x(organ(t, 1), 0), &x(organ(t, 2), 0));
    }
  }
  return count;
}

// Refuse an instrument whose track, replay or device home (home_pose) starts it through the organ's walls at rest (the sweeps assume an
// intersection-free start), naming the scene file, the key and the start position.
void require_clear_start(const Scene& scene, const Model& m) {
  const std::vector<Box> boxes = organ_boxes(m, m.mesh.rest);
  for (size_t i = 0; i < m.instruments.size(); ++i) {
    const InstrumentSpec& spec = scene.instruments[i];
    const Pose start = home_pose(spec);
    const Instrument& instrument = m.instruments[i].instrument;
    const double opening = commanded_opening(spec.openings, instrument.rest_opening, 0.0);
    const std::vector<Points> posed = posed_parts(instrument, start, opening);
    long count = 0;
    for (size_t j = 0; j < posed.size(); ++j)
      count += part_intersections(m, boxes, m.mesh.rest, static_cast<size_t>(m.instruments[i].first_part) + j, posed[j]);
    if (count == 0) continue;
    const char* key = spec.drive == InstrumentDrive::kReplay ? "replay"
                      : spec.drive == InstrumentDrive::kDevice ? "to_organ" : "track";
    throw InputError(scene.path + ": instruments[" + std::to_string(i) + "]." + key + ": starts through the organ's " +
                     "walls at t = 0 (" + std::to_string(count) + " intersecting triangle pairs; value position " +
                     values_text(start.position.data(), 3) + ")");
  }
}

}  // namespace

void compile_instruments(const Scene& scene, Model& m) {
  if (scene.instruments.empty()) return;
  // The organ surface the instruments touch: the outer wall, then the inner wall (a scope inside the lumen).
  const Tris& outer = m.outer_wall();
  const Tris& inner = m.inner_wall();
  m.tool_target_tris.resize(outer.rows() + inner.rows(), 3);
  m.tool_target_tris.topRows(outer.rows()) = outer;
  m.tool_target_tris.bottomRows(inner.rows()) = inner;
  m.tool_target_surface = std::make_shared<const collision::CollisionSurface>(m.tool_target_tris, m.mesh.rest);
  // Each instrument's parts (validated when the scene loaded), one collision surface per part.
  for (size_t i = 0; i < scene.instruments.size(); ++i) {
    const InstrumentSpec& spec = scene.instruments[i];
    CompiledInstrument ci;
    ci.name = spec.name;
    ci.instrument = make_instrument(spec.shape, scene.path + ": instruments[" + std::to_string(i) + "].shape");
    ci.drive = spec.drive;
    ci.openings = spec.openings;
    ci.grasp = spec.grasp;
    ci.first_part = static_cast<int>(m.tool_parts.size());
    for (size_t j = 0; j < ci.instrument.parts.size(); ++j) {
      const RigidMesh& mesh = ci.instrument.parts[j].mesh;
      m.tool_parts.push_back({static_cast<int>(i), static_cast<int>(j),
                              std::make_shared<const collision::CollisionSurface>(mesh.tris, mesh.points)});
    }
    if (spec.name == scene.render.scope_instrument) m.scope_instrument = static_cast<int>(i);
    m.instruments.push_back(std::move(ci));
  }
  require_clear_start(scene, m);
}

void detect_tool_contacts(const Model& model, State& state, const Points& x0, const Points& x1, double gap,
                          std::vector<HeldContact>& out, collision::CollisionStats* stats) {
  std::vector<collision::PairContact> pairs;
  for (size_t p = 0; p < model.tool_parts.size(); ++p) {
    collision::CollisionStats part_stats;
    collision::detect_pair(*model.tool_target_surface, *state.organ_tool_workspace, x0, x1,
                           *model.tool_parts[p].surface, *state.tool_workspaces[p], state.tool_points[p],
                           state.tool_target[p], gap, pairs, &part_stats);
    // A contact whose organ nodes the part's instrument holds is frozen, not a constraint.
    for (const collision::PairContact& pc : pairs) {
      const HeldContact h = held_of(pc, static_cast<int>(p));
      if (!held_by_own_instrument(model, state, h)) out.push_back(h);
    }
    if (!stats) continue;
    stats->bv_overlaps += part_stats.bv_overlaps;
    stats->feature_tests += part_stats.feature_tests;
    stats->contacts += part_stats.contacts;
  }
}

HeldContact remeasured(const HeldContact& h, const State& state) {
  Eigen::Vector3d p[4];
  for (int k = 0; k < 4; ++k) {
    const Points& from = h.on_tool(k) ? state.tool_points[static_cast<size_t>(h.part)] : state.x;
    p[k] = from.row(h.c.v[k]).transpose();
  }
  HeldContact out = h;
  out.c.toi = 0.0;
  if (h.c.kind == collision::FeatureKind::VertexFace) {
    const Eigen::Vector3d w = collision::closest_on_triangle(p[0], p[1], p[2], p[3]);
    out.c.s = w[1];
    out.c.t = w[2];
  } else {
    collision::segment_segment_closest(p[0], p[1], p[2], p[3], out.c.s, out.c.t);
  }
  return out;
}

physics::ContactRow tool_contact_row(const HeldContact& h, const Model& model, const State& state, const Points& x0,
                                     const Points& x1, double gap) {
  const Points& y0 = state.tool_points[h.part];
  const Points& y1 = state.tool_target[h.part];
  // The part's vertices move as prescribed (all of their end position is fixed); the organ's with u.
  RowVertices rv;
  for (int k = 0; k < 4; ++k) {
    const int v = h.c.v[k];
    const bool tool = h.on_tool(k);
    rv.node[k] = tool ? -1 : v;
    rv.x0[k] = tool ? y0.row(v).transpose() : x0.row(v).transpose();
    rv.x1[k] = tool ? y1.row(v).transpose() : x1.row(v).transpose();
    rv.fixed[k] = tool ? y1.row(v).transpose() : model.mesh.rest.row(v).transpose();
  }
  return row_of(h.c, rv, gap);
}

long count_tool_intersections(const Model& model, const Points& x, const std::vector<Points>& parts) {
  const std::vector<Box> boxes = organ_boxes(model, x);
  long count = 0;
  for (size_t p = 0; p < model.tool_parts.size(); ++p) count += part_intersections(model, boxes, x, p, parts[p]);
  return count;
}

std::vector<InstrumentRecord> instrument_records(const Model& model, const State& state,
                                                 const std::vector<HeldContact>& contacts,
                                                 const std::vector<physics::ContactRow>& rows,
                                                 const Eigen::VectorXd& lambda) {
  std::vector<InstrumentRecord> recs(model.instruments.size());
  for (size_t i = 0; i < recs.size(); ++i) {
    recs[i].name = model.instruments[i].name;
    recs[i].position = state.tool_pose[i].position;
    recs[i].rotation = state.tool_pose[i].rotation;
    recs[i].opening = state.tool_opening[i];
    recs[i].held_nodes = state.grasps[i].nodes;
  }
  // The holds' forces on the organ, at the held nodes where they ended the frame: minus that on the instrument.
  const GraspHolds& g = state.grasp_holds;
  for (size_t a = 0; a < g.held.points.size() && 3 * static_cast<Eigen::Index>(a) < state.grasp_force.size(); ++a) {
    InstrumentRecord& rec = recs[static_cast<size_t>(g.instrument[a])];
    const Eigen::Vector3d f = -state.grasp_force.segment<3>(3 * static_cast<Eigen::Index>(a));
    const Eigen::Vector3d arm = state.x.row(g.held.points[a].node[0]).transpose() - rec.position;
    rec.force += f;
    rec.torque += arm.cross(f);
  }
  // Each tool row's force on the part's vertices, where they ended the frame; torque about the instrument's origin.
  for (size_t r = 0; r < contacts.size() && static_cast<Eigen::Index>(r) < lambda.size(); ++r) {
    const HeldContact& h = contacts[r];
    if (!h.is_tool()) continue;
    InstrumentRecord& rec = recs[static_cast<size_t>(model.tool_parts[h.part].instrument)];
    ++rec.contacts;
    double w[4];
    weights_of(h.c, w);
    for (int k = 0; k < 4; ++k) {
      if (!h.on_tool(k)) continue;
      const Eigen::Vector3d f = lambda[static_cast<Eigen::Index>(r)] * w[k] * rows[r].n;
      const Eigen::Vector3d arm = state.tool_points[h.part].row(h.c.v[k]).transpose() - rec.position;
      rec.force += f;
      rec.torque += arm.cross(f);
    }
  }
  return recs;
}

namespace {

// The hold's rows for the stiffness: per held point and axis, a row of unit normal along the axis on the point's
// nodes (the hold keeps that displacement), and the instrument whose grasp holds it (-1: a held probe, which no
// instrument moves).
void append_hold_rows(const Model& model, const State& state, std::vector<physics::ContactRow>& rows,
                      std::vector<int>& holder) {
  const bool grasped = !state.grasp_holds.empty();
  const physics::HeldPoints* held = grasped ? &state.grasp_holds.held : model.integrator->held_points();
  if (!held) return;
  for (size_t a = 0; a < held->points.size(); ++a)
    for (int axis = 0; axis < 3; ++axis) {
      physics::ContactRow row;
      for (int k = 0; k < 3; ++k) {
        row.node[k] = held->points[a].node[k];
        row.weight[k] = held->points[a].weight[k];
      }
      row.n = Eigen::Vector3d::Unit(axis);
      rows.push_back(row);
      holder.push_back(grasped ? state.grasp_holds.instrument[a] : -1);
    }
}

}  // namespace

void add_tool_stiffness(const Model& model, State& state, const std::vector<HeldContact>& contacts,
                        const std::vector<physics::ContactRow>& rows, const Eigen::VectorXd& lambda,
                        std::vector<InstrumentRecord>& records) {
  if (!state.compliance || rows.size() != contacts.size() || static_cast<size_t>(lambda.size()) != rows.size()) return;
  // The pushing rows, and whether any is a tool's.
  std::vector<physics::ContactRow> pushing;
  std::vector<size_t> index;
  bool tool = false;
  for (size_t r = 0; r < rows.size(); ++r)
    if (lambda[static_cast<Eigen::Index>(r)] > 0.0) {
      pushing.push_back(rows[r]);
      index.push_back(r);
      tool = tool || contacts[r].is_tool();
    }
  if (!tool && state.grasp_holds.empty()) return;
  // The holds' rows after them (a grasper's move carries its held nodes along).
  const Eigen::Index m_contact = static_cast<Eigen::Index>(pushing.size());
  std::vector<int> holder;
  append_hold_rows(model, state, pushing, holder);
  const Eigen::MatrixXd a = physics::coupling_matrix(*state.compliance, pushing);
  const Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> solver(a);
  // Per instrument: G over the pushing rows and the holds' rows, K = G^T A^-1 G.
  const Eigen::Index m = static_cast<Eigen::Index>(pushing.size());
  for (size_t i = 0; i < records.size(); ++i) {
    Eigen::MatrixXd g = Eigen::MatrixXd::Zero(m, 3);
    for (Eigen::Index a_row = 0; a_row < m_contact; ++a_row) {
      const HeldContact& h = contacts[index[static_cast<size_t>(a_row)]];
      if (!h.is_tool() || static_cast<size_t>(model.tool_parts[h.part].instrument) != i) continue;
      double w[4];
      weights_of(h.c, w);
      for (int k = 0; k < 4; ++k)
        if (h.on_tool(k)) g.row(a_row) += w[k] * pushing[static_cast<size_t>(a_row)].n.transpose();
    }
    // A held row's target moves with its grasper by dx (the row value by -n . dx, the contacts' sign convention).
    for (Eigen::Index a_row = m_contact; a_row < m; ++a_row)
      if (holder[static_cast<size_t>(a_row - m_contact)] == static_cast<int>(i))
        g.row(a_row) = -pushing[static_cast<size_t>(a_row)].n.transpose();
    if (g.isZero(0.0)) continue;
    const Eigen::Matrix3d k = g.transpose() * solver.solve(g);
    records[i].stiffness = 0.5 * (k + k.transpose());
  }
}

}  // namespace lumen::engine
