#pragma once
// A whole session: the fixed-step frame loop, rendering, writers, budget check, report.
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "engine/report.hpp"
#include "engine/simulation.hpp"
#include "physics/fem.hpp"
#include "render/writers.hpp"

namespace lumen::engine {

struct SessionOptions {
  std::string out_dir;          // where outputs go (run); empty for bench
  int frames = -1;              // override the scene's frame count (> 0)
  bool render = true;           // draw every frame (bench draws too, to measure it)
  bool write_frames = true;     // PNG frames (run)
  std::string video_path;       // MP4 path, empty for none
  bool export_surface = false;  // DIR/surface/inner_000001.obj ...
  bool export_volume = false;   // DIR/volume/volume_000001.vtu ... and the collection DIR/volume.pvd
  physics::LinearMaterial volume_material;  // the scene's elasticity, for the exported von Mises stress
  bool check = false;           // exact intersection count of the inner wall on every frame
  // Solve the interior of a contact frame's whole-mesh correction on the second core while the frame renders (when
  // it would back-substitute; State::defer_interior). Off: the frame does it before rendering, as without a render.
  bool overlap_interior = true;
  // ... and leave it solving into the next frame, until that frame's response is done (State::pipeline_interior),
  // for a model whose prediction reads no committed state (linear quasi-static), in a session with no on_frame and
  // no volume export (they read the whole state of every frame). Off: each frame waits for its own after the render.
  bool pipeline_interior = true;
  bool progress = false;        // progress line on stderr
  bool classify_overlaps = false;  // k-DOP study: split bounding-volume overlaps into with / without contact
  // Called after every frame with the committed state (off the frame's budget: not timed), e.g. by studies
  // that measure the deformed shape. Empty: none.
  std::function<void(const Model&, const State&, const FrameRecord&)> on_frame;
  // Called once after the last frame with the committed state and the last frame's record (not timed). Empty: none.
  std::function<void(const Model&, const State&, const FrameRecord&)> on_end;
  // Called before frame i (0-based) starts; false ends the session there (an interrupt). Paces a real-time
  // session (lumen serve). Empty: every frame runs.
  std::function<bool(int)> before_frame;
};

struct SessionResult {
  std::vector<FrameRecord> frames;
  render::WriterStats writer;
  nlohmann::json report;        // what report.json holds
};

// Runs the model's frames with its input sources (make_inputs of the scene it compiled, one per probe; a caller
// may swap in a device). Outputs are written under temporary names and renamed when complete.
SessionResult run_session(const Model& model, Inputs inputs, const SessionOptions& options);
// The same on inputs the caller keeps (to read its sources after the session).
SessionResult run_session_on(const Model& model, Inputs& inputs, const SessionOptions& options);

// The camera of render.camera {"centreline": {"from", "to"}} when `frame` frames of a session of `frames` are done
// (0: the rest view before the first frame): the eye on the centreline at arc length from + (to - from) frame / frames,
// looking along the centreline's tangent there in the direction of travel, up along its normal (the frame the tube's
// rings are swept with). The model must have a centreline flight (render.centreline_flight); frames >= 1.
render::CameraPose centreline_camera(const Model& model, int frame, int frames);
// The same camera carried by the deformed lumen at positions x (n_nodes x 3, metres): the eye moves with the centres
// of the tube's rings on either side (the mean of each ring's inner-wall nodes: its displacement interpolated along
// the arc length), and the view turns by the least rotation that takes the rest chord between those two centres to
// the deformed one. At rest positions it is the rest camera; under a rigid translation, the same translated.
render::CameraPose centreline_camera(const Model& model, const Points& x, int frame, int frames);

// The renderer's framing of the model: from its rest geometry (render::frame_organ over the inner wall), with a
// centreline flight's lumen radius the narrowest ring's along the flight.
render::Framing session_framing(const Model& model);

// What the renderer draws of the state after state.frame frames of a session of `frames`: the organ's walls, the
// instruments, contact flags, probe arrows, and the endoscope's placed camera (on its instrument, or on the
// centreline flight).
render::FrameView session_frame_view(const Model& model, const State& state, int frames);

// Writes the inner wall at positions x as a Wavefront OBJ through assimp, atomically.
void export_surface_obj(const std::string& path, const Points& x, const Tris& tris);

}  // namespace lumen::engine
