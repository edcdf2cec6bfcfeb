#include "engine/session.hpp"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstddef>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <assimp/Exporter.hpp>
#include <assimp/scene.h>
#include <Eigen/Geometry>

#include "collision/self_collision.hpp"
#include "engine/mesh_check.hpp"
#include "engine/volume_export.hpp"
#include "physics/pair_mesh.hpp"
#include "physics/swept_tube.hpp"
#include "render/renderer.hpp"

namespace lumen::engine {
namespace fs = std::filesystem;
namespace {

using Clock = std::chrono::steady_clock;

// Remove outputs of an earlier run that this run would not overwrite (stale frames).
void clear_stale(const fs::path& dir, const std::string& prefix) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return;
  for (const auto& e : fs::directory_iterator(dir, ec))
    if (e.path().filename().string().rfind(prefix, 0) == 0) fs::remove(e.path(), ec);
}

std::string numbered(const fs::path& dir, const char* prefix, int i, const char* ext) {
  char name[64];
  std::snprintf(name, sizeof name, "%s%06d%s", prefix, i, ext);
  return (dir / name).string();
}

}  // namespace

render::CameraPose centreline_camera(const Model& model, int frame, int frames) {
  return centreline_camera(model, model.mesh.rest, frame, frames);
}

render::CameraPose centreline_camera(const Model& model, const Points& x, int frame, int frames) {
  const RenderSpec& rs = model.render;
  if (!rs.centreline_flight || model.flight_frames.empty() || frames < 1)
    throw std::logic_error("centreline_camera: the model has no centreline flight, or frames < 1");
  // Constant speed along the arc length over the session; the eye looks the way it travels.
  const double progress = static_cast<double>(std::clamp(frame, 0, frames)) / frames;
  const double s = rs.flight_from + (rs.flight_to - rs.flight_from) * progress;
  const physics::CentrelineFrame f = physics::frame_at_arc_length(model.flight_frames, model.flight_arc, s);
  const double travel = rs.flight_to > rs.flight_from ? 1.0 : -1.0;
  // The rings j, j + 1 around s (clamped to the tube's), their centres at rest and at x, and the share w of j + 1.
  const std::vector<double>& ring_s = model.flight_ring_s;
  const int around = model.flight_ring_around;
  if (ring_s.size() < 2 || around < 1) return render::CameraPose{f.point, travel * f.tangent, f.normal};
  const size_t j = std::min(static_cast<size_t>(std::max<std::ptrdiff_t>(
                                std::upper_bound(ring_s.begin(), ring_s.end(), s) - ring_s.begin() - 1, 0)),
                            ring_s.size() - 2);
  const double w = std::clamp((s - ring_s[j]) / (ring_s[j + 1] - ring_s[j]), 0.0, 1.0);
  auto centre = [&](const Points& p, size_t ring) {
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    const int* nodes = model.flight_ring_inner.data() + ring * static_cast<size_t>(around);
    for (int i = 0; i < around; ++i) c += p.row(nodes[i]).transpose();
    return Eigen::Vector3d(c / around);
  };
  const Eigen::Vector3d rest0 = centre(model.mesh.rest, j), rest1 = centre(model.mesh.rest, j + 1);
  const Eigen::Vector3d now0 = centre(x, j), now1 = centre(x, j + 1);
  const Eigen::Vector3d eye = f.point + (1.0 - w) * (now0 - rest0) + w * (now1 - rest1);
  const Eigen::Quaterniond turn = Eigen::Quaterniond::FromTwoVectors(rest1 - rest0, now1 - now0);
  return render::CameraPose{eye, turn * (travel * f.tangent), turn * f.normal};
}

// Camera framing from the rest geometry: the mesh's bounding box, and the lumen's axis, radius and length from
// the inner-wall nodes (no scene fields: the same for generated tubes and imported organs); a centreline flight
// sees the lumen of the tube's own radius (the principal axis of a bent tube is not its lumen's).
render::Framing session_framing(const Model& model) {
  const auto& rest = model.mesh.rest;
  render::Framing f = render::frame_organ(rest.data(), static_cast<int>(rest.rows()), model.inner_wall().data(),
                                          static_cast<int>(model.inner_wall().rows()));
  if (model.render.centreline_flight && model.flight_lumen_radius > 0.0 && model.flight_lumen_radius < f.radius)
    f.lumen_radius = model.flight_lumen_radius;
  return f;
}

// What the renderer draws of the current state: walls, contact flags, probes at their attachment points.
render::FrameView session_frame_view(const Model& model, const State& state, int frames) {
  render::FrameView view;
  view.positions = state.x.data();
  view.n_points = static_cast<int>(state.x.rows());
  // The organ's drawn surfaces, outermost first.
  for (const DrawnSurface& d : model.drawn) {
    const Tris& tris = model.mesh.surfaces[d.surface].tris;
    render::Surface s;
    s.triangles = tris.data();
    s.n_triangles = static_cast<int>(tris.rows());
    s.style = d.style;
    view.surfaces.push_back(s);
  }
  // The instruments, as metal over their posed points; the one carrying the endoscope places the camera instead
  // (eye at its tip, looking out of it along its -y, up its +z) and is not drawn.
  for (const ToolPart& part : model.tool_parts) {
    if (part.instrument == model.scope_instrument) continue;
    const Points& points = state.tool_points[static_cast<size_t>(&part - model.tool_parts.data())];
    const Tris& tris = model.instruments[static_cast<size_t>(part.instrument)].instrument.parts[static_cast<size_t>(part.part)].mesh.tris;
    render::Surface s;
    s.triangles = tris.data();
    s.n_triangles = static_cast<int>(tris.rows());
    s.positions = points.data();
    s.n_points = static_cast<int>(points.rows());
    s.style = render::SurfaceStyle::metal();
    view.surfaces.push_back(s);
  }
  if (model.scope_instrument >= 0) {
    const Pose& pose = state.tool_pose[static_cast<size_t>(model.scope_instrument)];
    view.camera = render::CameraPose{pose.position, pose.rotation * -Eigen::Vector3d::UnitY(),
                                     pose.rotation * Eigen::Vector3d::UnitZ()};
  }
  // The colonoscopy view: the endoscope on the centreline, where the flight is after the frames done, carried by the
  // deformed lumen.
  if (model.render.centreline_flight) view.camera = centreline_camera(model, state.x, state.frame, frames);
  view.contact = state.in_contact.data();
  view.force_scale = model.render.force_scale;
  for (size_t p = 0; p < state.samples.size(); ++p) {
    render::ProbeGlyph g;
    g.point = point_of(state.x, model.probe_points[p]);
    g.force = state.samples[p].force;
    view.probes.push_back(g);
  }
  return view;
}

void export_surface_obj(const std::string& path, const Points& x, const Tris& tris) {
  // Compact the surface's vertices (the index map onto the mesh) into one assimp mesh.
  std::vector<int> local(x.rows(), -1);
  std::vector<int> used;
  for (int t = 0; t < tris.rows(); ++t)
    for (int k = 0; k < 3; ++k)
      if (local[tris(t, k)] < 0) {
        local[tris(t, k)] = static_cast<int>(used.size());
        used.push_back(tris(t, k));
      }
  aiScene scene;
  scene.mRootNode = new aiNode();
  scene.mRootNode->mNumMeshes = 1;
  scene.mRootNode->mMeshes = new unsigned int[1]{0};
  scene.mNumMaterials = 1;
  scene.mMaterials = new aiMaterial*[1]{new aiMaterial()};
  scene.mNumMeshes = 1;
  scene.mMeshes = new aiMesh*[1]{new aiMesh()};
  aiMesh* mesh = scene.mMeshes[0];
  mesh->mMaterialIndex = 0;
  mesh->mPrimitiveTypes = aiPrimitiveType_TRIANGLE;
  mesh->mNumVertices = static_cast<unsigned>(used.size());
  mesh->mVertices = new aiVector3D[used.size()];
  for (size_t i = 0; i < used.size(); ++i)
    mesh->mVertices[i] = aiVector3D(static_cast<ai_real>(x(used[i], 0)), static_cast<ai_real>(x(used[i], 1)),
                                    static_cast<ai_real>(x(used[i], 2)));
  mesh->mNumFaces = static_cast<unsigned>(tris.rows());
  mesh->mFaces = new aiFace[tris.rows()];
  for (int t = 0; t < tris.rows(); ++t) {
    aiFace& face = mesh->mFaces[t];
    face.mNumIndices = 3;
    face.mIndices = new unsigned int[3];
    for (int k = 0; k < 3; ++k) face.mIndices[k] = static_cast<unsigned>(local[tris(t, k)]);
  }
  // Export under a temporary name, then rename.
  const std::string tmp = path + ".tmp.obj";
  Assimp::Exporter exporter;
  if (exporter.Export(&scene, "objnomtl", tmp) != AI_SUCCESS) {
    fs::remove(tmp);
    throw std::runtime_error(path + ": surface export failed: " + exporter.GetErrorString());
  }
  fs::rename(tmp, path);
}

namespace {

// The session's outputs: renderer on this thread, frame and video writers on their own.
struct SessionOutputs {
  fs::path out;
  bool write_frames = false;
  bool export_surface = false;
  bool export_volume = false;
  std::vector<std::pair<double, std::string>> volume_frames;  // exported frames: time, file relative to `out`
  std::unique_ptr<render::Renderer> renderer;
  std::unique_ptr<render::FrameWriter> writer;
  int frames = 1;  // the session's frame count (a centreline flight spans it)
};

// Output folders (validated by the caller; stale numbered outputs of earlier runs are removed), renderer, writers.
SessionOutputs open_outputs(const Model& model, const SessionOptions& opt) {
  SessionOutputs o;
  const RenderSpec& rs = model.render;
  o.out = fs::path(opt.out_dir);
  o.write_frames = opt.render && opt.write_frames && !opt.out_dir.empty();
  o.export_surface = opt.export_surface && !opt.out_dir.empty();
  if (o.write_frames) {
    fs::create_directories(o.out / "frames");
    clear_stale(o.out / "frames", "frame_");
  }
  if (o.export_surface) {
    fs::create_directories(o.out / "surface");
    clear_stale(o.out / "surface", "inner_");
  }
  o.export_volume = opt.export_volume && !opt.out_dir.empty();
  if (o.export_volume) {
    fs::create_directories(o.out / "volume");
    clear_stale(o.out / "volume", "volume_");
  }
  if (!opt.render) return o;
  o.renderer = std::make_unique<render::Renderer>(rs.width, rs.height, rs.camera, session_framing(model));
  if (o.write_frames || !opt.video_path.empty())
    o.writer = std::make_unique<render::FrameWriter>(o.write_frames ? (o.out / "frames").string() : std::string(),
                                                     opt.video_path, rs.width, rs.height,
                                                     static_cast<int>(std::lround(model.fps)));
  return o;
}

// One frame: the step's first half, render and hand the image to the writer (while the interior of the
// whole-mesh correction may be solving on the second core), the step's second half, the optional exact check,
// export, observe. The total is the simulation thread's work for the frame without the check, the export and the
// observer.
FrameRecord run_frame(const Model& model, const SessionOptions& opt, SessionOutputs& io, Inputs& inputs,
                      State& state) {
  FrameRecord rec;
  const auto frame_start = Clock::now();
  step_begin(model, inputs, state, rec);
  // Render what step_begin placed (every node the renderer reads) and hand the image to the writer thread.
  if (io.renderer) {
    const auto r0 = Clock::now();
    render::Image image;
    io.renderer->draw(session_frame_view(model, state, io.frames), image);
    rec.ms[kRender] = std::chrono::duration<double, std::milli>(Clock::now() - r0).count();
    if (io.writer) io.writer->push(std::move(image));
  }
  step_end(model, inputs, state, rec);
  rec.ms[kTotal] = std::chrono::duration<double, std::milli>(Clock::now() - frame_start).count();
  rec.over_budget = rec.ms[kTotal] > model.budget_ms;
  // Optional exact intersection count (not part of the frame's budget).
  if (opt.check) {
    rec.intersecting_pairs = collision::count_intersecting_pairs(state.x, model.collision_tris);
    if (!model.instruments.empty())
      rec.instrument_intersecting_pairs = count_tool_intersections(model, state.x, state.tool_points);
  }
  // Surface and volume export and observer (off the budget, like the writers).
  if (io.export_surface)
    export_surface_obj(numbered(io.out / "surface", "inner_", rec.frame, ".obj"), state.x, model.inner_wall());
  if (io.export_volume) {
    const std::string file = numbered("volume", "volume_", rec.frame, ".vtu");
    write_text_file((io.out / file).string(), volume_vtu(model, state, opt.volume_material));
    io.volume_frames.emplace_back(rec.t, file);
  }
  if (opt.on_frame) opt.on_frame(model, state, rec);
  return rec;
}

// Per-session sums of the per-frame records.
struct SessionTotals {
  long over_budget = 0, fallbacks = 0, inverted_frames = 0, failures = 0, intersecting_frames = 0;
  long instrument_intersecting_frames = 0;
  long bv_overlaps = 0, feature_tests = 0, contacts = 0, iterations = 0, preconditioner_failures = 0;
};
SessionTotals totals_of(const std::vector<FrameRecord>& frames) {
  SessionTotals t;
  for (const auto& f : frames) {
    t.over_budget += f.over_budget;
    t.bv_overlaps += f.bv_overlaps;
    t.feature_tests += f.feature_tests;
    t.contacts += f.contacts;
    t.iterations += f.response_iterations;
    t.fallbacks += f.fallback;
    t.inverted_frames += f.inverted_elements > 0;
    t.failures += f.numerical_failure;
    t.intersecting_frames += f.intersecting_pairs > 0;
    t.instrument_intersecting_frames += f.instrument_intersecting_pairs > 0;
    t.preconditioner_failures += f.preconditioner_failures;
  }
  return t;
}

// The session report (report.json), built in one place.
nlohmann::json session_report(const Model& model, const SessionOptions& opt, const SessionResult& result,
                              const State& state) {
  const RenderSpec& rs = model.render;
  const SessionTotals t = totals_of(result.frames);
  nlohmann::json r;
  r["scene"] = model.name;
  r["scene_file"] = model.scene_path;
  r["frames"] = static_cast<long>(result.frames.size());
  r["fps"] = model.fps;
  r["budget_ms"] = model.budget_ms;
  r["over_budget_frames"] = t.over_budget;
  r["mesh"] = {{"nodes", model.mesh.n_nodes()},
               {"tets", model.n_elements},
               {"inner_triangles", model.inner_wall().rows()},
               {"outer_triangles", model.outer_wall().rows()}};
  r["mesh"].update(mesh_quality_json(physics::mesh_quality(model.mesh.rest, model.mesh.tets)));
  r["mesh"]["source"] = name_of(model.mesh_type);
  r["mesh"]["build_ms"] = model.mesh_build_ms;
  if (model.mesh_type == MeshType::kSweptTube) r["mesh"]["clamped_rings"] = model.clamped_rings;
  if (!model.mesh_file.empty()) r["mesh"]["file"] = model.mesh_file;
  if (model.mesh_type == MeshType::kSurfaceWall) {
    r["mesh"]["clamped_vertices"] = model.clamped_vertices;
    r["mesh"]["untangled_vertices"] = model.untangled_vertices;
  }
  // A surface wall or pair remeshed to a target edge: the target, the files' triangles before, and the time.
  if (model.remesh_target_edge > 0.0) {
    r["mesh"]["target_edge_m"] = model.remesh_target_edge;
    r["mesh"]["file_triangles"] = model.remesh_file_triangles;
    r["mesh"]["remesh_ms"] = model.remesh_ms;
  }
  if (model.mesh_type == MeshType::kSurfacePair) {
    r["mesh"]["outer_file"] = model.mesh_outer_file;
    r["mesh"]["mesher"] = physics::pair_mesher_name(model.pair_mesher);
    if (!model.gmsh_failure.empty()) r["mesh"]["gmsh_failure"] = model.gmsh_failure;
    r["mesh"]["mesher_ms"] = model.mesher_ms;
    r["mesh"]["surface_check_ms"] = model.surface_check_ms;
    r["mesh"]["mesher_added_nodes"] = model.mesher_added_nodes;
  }
  r["model"] = {{"material", name_of(model.material)}, {"element", name_of(model.element)},
                {"solver", name_of(model.solver)},
                {"tangent", name_of(model.tangent)},
                {"method", name_of(model.method)}, {"compile_seconds", model.compile_seconds}};
  r["collision"] = {{"self", model.collision.self}, {"kdop", model.collision.kdop},
                    {"response", name_of(model.collision.response)}, {"lcp", name_of(model.collision.lcp)},
                    {"recheck", name_of(model.collision.recheck)},
                    {"detection", name_of(model.collision.detection)},
                    {"coupling", name_of(model.collision.coupling)}, {"gap_m", model.collision.gap},
                    {"surfaces", model.collision.outer_wall ? nlohmann::json{"inner", "outer"} : nlohmann::json{"inner"}}};
  r["render"] = {{"enabled", opt.render}, {"width", rs.width}, {"height", rs.height}, {"camera", name_of(rs.camera)}};
  if (!rs.scope_instrument.empty()) r["render"]["endoscope_on"] = rs.scope_instrument;
  if (rs.centreline_flight)
    r["render"]["centreline_flight_m"] = {{"from", rs.flight_from}, {"to", rs.flight_to},
                                          {"lumen_radius", model.flight_lumen_radius}};
  r["stages"] = stages_json(result.frames);
  r["writer"] = {{"frames", result.writer.frames}, {"busy_seconds", result.writer.busy_seconds},
                 {"frames_per_second", result.writer.frames_per_second()},
                 {"keeps_up", result.writer.frames == 0 || result.writer.frames_per_second() >= model.fps}};
  r["collision_totals"] = {{"bv_overlaps", t.bv_overlaps}, {"feature_tests", t.feature_tests}, {"contacts", t.contacts},
                           {"response_iterations", t.iterations}};
  if (opt.classify_overlaps && state.detector) {
    const auto o = state.detector->overlap_totals();
    r["overlap_classification"] = {{"detect_calls", o.calls}, {"bv_overlaps", o.overlaps},
                                   {"with_contact", o.overlaps_with_contact},
                                   {"false_positives", o.overlaps - o.overlaps_with_contact},
                                   {"separate_bv_overlaps", o.separate_overlaps},
                                   {"separate_false_positives", o.separate_overlaps - o.separate_with_contact}};
  }
  r["fallback_frames"] = t.fallbacks;
  r["frames_with_inverted_elements"] = t.inverted_frames;
  r["numerical_failures"] = t.failures;
  r["preconditioner_failures"] = t.preconditioner_failures;
  if (opt.check) r["frames_with_intersections"] = t.intersecting_frames;
  if (opt.check && !model.instruments.empty())
    r["frames_with_instrument_intersections"] = t.instrument_intersecting_frames;
  nlohmann::json per = nlohmann::json::array();
  for (const auto& f : result.frames) per.push_back(frame_json(f));
  r["per_frame"] = std::move(per);
  return r;
}

}  // namespace

SessionResult run_session(const Model& model, Inputs inputs, const SessionOptions& opt) {
  return run_session_on(model, inputs, opt);
}

SessionResult run_session_on(const Model& model, Inputs& inputs, const SessionOptions& opt) {
  SessionResult result;
  const int frames = opt.frames > 0 ? opt.frames : model.frames;
  SessionOutputs io = open_outputs(model, opt);
  io.frames = std::max(frames, 1);
  State state = make_state(model);
  state.defer_interior = io.renderer != nullptr && opt.overlap_interior;
  state.pipeline_interior = state.defer_interior && opt.pipeline_interior && !model.integrator->predicts_from_state() &&
                            model.coupling_stiffness == 0.0 && !opt.on_frame && !opt.export_volume;
  // Warm-up draw of the rest state: the GL driver's one-time set-up (shader compilation) happens at load time,
  // not in the first frame's budget.
  if (io.renderer) {
    render::Image warm;
    io.renderer->draw(session_frame_view(model, state, io.frames), warm);
  }
  if (opt.classify_overlaps && state.detector) state.detector->set_classify_overlaps(true);

  // The frames, with a progress line on a terminal.
  result.frames.reserve(frames);
  const bool tty = opt.progress && isatty(fileno(stderr));
  long over_budget = 0;
  const auto session_start = Clock::now();
  for (int i = 0; i < frames; ++i) {
    if (opt.before_frame && !opt.before_frame(i)) break;
    result.frames.push_back(run_frame(model, opt, io, inputs, state));
    file_commits(state, result.frames.data(), result.frames.size());  // (a pipelined last frame's commit)
    over_budget += result.frames.back().over_budget;
    if (tty && (i % 10 == 9 || i + 1 == frames)) {
      const double wall = std::chrono::duration<double>(Clock::now() - session_start).count();
      std::fprintf(stderr, "\rframe %d of %d  %.1f fps  over budget %ld", i + 1, frames, (i + 1) / wall, over_budget);
      std::fflush(stderr);
    }
  }
  if (tty) std::fprintf(stderr, "\n");
  // The last frame's commit, when pipelined.
  settle(model, state);
  file_commits(state, result.frames.data(), result.frames.size());
  if (opt.on_end && !result.frames.empty()) opt.on_end(model, state, result.frames.back());
  if (io.writer) result.writer = io.writer->finish();
  if (io.export_volume) write_text_file((io.out / "volume.pvd").string(), volume_pvd(io.volume_frames));
  result.report = session_report(model, opt, result, state);
  return result;
}

}  // namespace lumen::engine
