#pragma once
// Instruments in a session: their rigid parts as collision surfaces of the compiled model, their swept contacts
// with the organ's walls (collision::detect_pair), the exact instrument-organ intersection count, and the
// contact force and torque on each instrument.
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "collision/surface.hpp"
#include "engine/instrument.hpp"
#include "engine/pose_track.hpp"
#include "engine/report.hpp"
#include "engine/response.hpp"
#include "engine/scene.hpp"

namespace lumen::engine {

struct Model;
struct State;

// An instrument of the compiled model: its rigid parts in its own frame and where its poses come from.
struct CompiledInstrument {
  std::string name;
  Instrument instrument;
  InstrumentDrive drive = InstrumentDrive::kTrack;
  int first_part = 0;  // its parts are Model::tool_parts[first_part, first_part + instrument.parts.size())
  std::vector<OpeningKey> openings;  // a grasper's commanded jaw opening over time (empty: its rest opening)
  GraspSpec grasp;                   // whether, and how, its jaws hold the tissue they close on
};

// One rigid part of an instrument as a collision surface over its own points (BVH topology over its points in
// the instrument frame: a rigid motion keeps it a good hierarchy).
struct ToolPart {
  int instrument = 0;  // index into Model::instruments
  int part = 0;        // index into its Instrument::parts
  std::shared_ptr<const collision::CollisionSurface> surface;
};

// Build the scene's instruments into the model: parts, their collision surfaces, and the organ surface they touch
// (the outer and inner walls, Model::tool_target_surface). Needs the model's mesh and walls. Throws InputError
// (scene file, instruments[i].track or .replay, the start position) for an instrument whose pose at t = 0 puts it
// through the organ's walls at rest.
void compile_instruments(const Scene& scene, Model& model);

// Every instrument part's contacts with the organ's walls for the organ motion x0 -> x1 (n_nodes x 3) while the
// part sweeps from state.tool_points to state.tool_target, within `gap`; appended to `out` (vertex ids of the
// organ are mesh nodes, those of the part index its points). stats accumulate when given.
void detect_tool_contacts(const Model& model, State& state, const Points& x0, const Points& x1, double gap,
                          std::vector<HeldContact>& out, collision::CollisionStats* stats);

// A contact held from the last frame (a tool contact, or a self-contact when h.part < 0), re-measured at the
// frame's start (organ at state.x, a part at state.tool_points): its features' closest points (barycentric s, t on
// the face, or along the two edges) and toi = 0. A held contact sits at the gap, so detection (which reports
// closer pairs) does not refresh it, and its features have slid along each other since it was found: its row
// then takes the direction between the closest points now, not between the points that were closest then.
HeldContact remeasured(const HeldContact& h, const State& state);

// The row of a tool contact: its organ vertices at x0 -> x1 (moving with u), its part's vertices at
// state.tool_points -> state.tool_target (kinematic).
physics::ContactRow tool_contact_row(const HeldContact& h, const Model& model, const State& state, const Points& x0,
                                     const Points& x1, double gap);

// Number of (instrument triangle, organ wall triangle) pairs that intersect with the parts at `parts` (one n x 3
// array per tool part) and the organ at x, by the exact predicates of collision/intersect.hpp; pairs whose
// bounding boxes are apart are skipped (they cannot intersect).
long count_tool_intersections(const Model& model, const Points& x, const std::vector<Points>& parts);

// Each instrument's record for the frame: its end pose and opening, the nodes it holds, and the force and torque
// the contacts and its hold put on it (the hold's: minus state.grasp_force at the held nodes' end positions). For a
// tool contact with multiplier lambda and row normal n, the force on the part's vertex k is lambda w_k n (w the
// contact's weights, so the sum over the four vertices is zero: the instrument gets minus what the organ gets);
// the torque is about the instrument's origin (its tip) at the end of the frame.
std::vector<InstrumentRecord> instrument_records(const Model& model, const State& state,
                                                 const std::vector<HeldContact>& contacts,
                                                 const std::vector<physics::ContactRow>& rows,
                                                 const Eigen::VectorXd& lambda);

// Each instrument's tip stiffness against translation (InstrumentRecord::stiffness) with the solve's pushing rows
// (lambda > 0, self-contacts included: they couple) held: a translation dx of the instrument moves the row values
// by G dx (row a of G: sum of the row's weights on the part's vertices times its normal), so the multipliers by
// -A^-1 G dx (A = H C H^T of the pushing rows on the contact compliance) and the force on it, G^T lambda, by
// -G^T A^-1 G dx: K = G^T A^-1 G. Held points (a grasp's nodes, or displacement-driven probes) are rows too, three
// per point along the axes: a grasper's translation moves its held nodes' targets by dx (its G rows -e_axis, so
// that G^T nu is minus the holding force, the hold's part of the force on it); a held probe's stay (G rows 0).
// Rows and contacts in the same order (the constraint response's).
void add_tool_stiffness(const Model& model, State& state, const std::vector<HeldContact>& contacts,
                        const std::vector<physics::ContactRow>& rows, const Eigen::VectorXd& lambda,
                        std::vector<InstrumentRecord>& records);

}  // namespace lumen::engine
