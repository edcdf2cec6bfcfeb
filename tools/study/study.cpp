// Speed against error: sweeps mesh resolution, model and solver tolerance over one squeeze-with-contact scene
// and the Lame cylinder, and writes one CSV row per configuration (frame time and errors against references).
//
//   lumen_study --out docs/study.csv --load-out docs/study_load.csv
//
// Per configuration:
//  - small deformation: the relative L2 error of the radial displacement on the plane-strain Lame cylinder
//    (physics::lame_error) at the configuration's around x layers (the corotational model equals the linear one
//    in the small-deformation limit, tests/physics/test_corotational.cpp, so it has the linear's error);
//  - large deformation with contact: two opposite probes (3 mm tips) pinch the tube shut with 0.1 N each, 1.25x
//    the force that first closes the lumen (self-collision on, the load ramped over 1 s): the wall ovalises
//    through about 90 degrees of rotation and the walls meet over an area. At the last frame: the top probe's
//    displacement (averaged over its tip), the lumen opening at the probe's section, the
//    contact area and the total contact force, each compared with the reference: the finest mesh,
//    corotational, tolerance 1e-5 (five load steps). err_shape is the larger of the first two (well-posed
//    quantities of the deformed shape), err_contact the larger of the last two (they hinge on which nodes are in
//    contact at the last frame, a discrete set), err_large the largest of all four;
//  - frame time: the whole frame (physics + collision + response + render 640x480 off-screen), median and p99
//    over the session's frames (30 frames at 20 fps by default: the quasi-static load increments of each frame
//    are twice those of a 40 fps session, a conservative measure).
// The load sweep (--load-out) shows when linear stops being enough: the pinch on the paper mesh up to the force
// that shuts the lumen, linear against corotational (tolerance 1e-6), probe displacement, over a range of forces.
// The sweeps against the converged CalculiX reference (--reference CSV): below first contact (--reference-out) and
// past closure (--closure-out, the tip, the contact force and the contact area at 0.03 N per tip); with --field-linear,
// --field-neohooke, --field-closure, also the inner wall's displacement against the reference's (relative L2 over
// the wall, engine/wall_field).
// The capacity sweep (--capacity-out) finds, per model and scenario, the largest mesh whose whole frame stays
// inside the 25 ms budget at p99: one probe at 40 fps (the real budget; 1 s ramp then held, 60 frames, rendered
// at 640x480, self-collision on) pinching with 0.02 N (the lumen stays open) or with the study's 0.1 N (walls
// in contact), on meshes growing by about 1.4x in tets from below the
// paper's, until p99 exceeds 25 ms.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "engine/equilibrium.hpp"
#include "engine/report.hpp"
#include "engine/scene.hpp"
#include "engine/session.hpp"
#include "engine/simulation.hpp"
#include "engine/wall_field.hpp"
#include "physics/lame.hpp"
#include "physics/support.hpp"

namespace fs = std::filesystem;
using namespace lumen;

namespace {

// One mesh resolution of the hollow cylinder (the paper's is 20 x 26 x 3).
struct Level {
  int around, along, layers;
};

// One configuration of the sweep.
struct Config {
  Level level;
  std::string element;  // "tet4" | "tet10"
  std::string model;    // "linear" | "corotational"
  double tolerance;     // corotational solve tolerance (0 for the direct linear solve)
  // Cells graded toward the tips (mesh.grading, largest / smallest cell; 1 = uniform): around toward 90 and 270
  // degrees, along toward the tips' section.
  double grade_around = 1.0, grade_along = 1.0;
  int tip_points = 7;  // load points per tip: 7 (centre and rim) or an equal-area spiral of that many
  int max_back_substitutions = 0;  // the corotational solve's work bound a frame (solver.max_back_substitutions; 0 none)
};

// What a squeeze session measured at its last frame, and its frame times.
struct Outcome {
  double probe_disp = 0, opening = 0, contact_area = 0, contact_force = 0;  // metres, metres, m^2, newtons
  double tip_mean = 0;  // metres: the top tip's load points' mean displacement along the pinch (-y), work-conjugate
  // The committed corotational state's equilibrium with its contacts at the last frame (NaN for other models):
  // |f_int(u) - f_probes - H^T lambda| on the free DOFs over |f_probes|, with the reported multipliers, and with
  // the multipliers that fit the state best (lambda >= 0, least squares), whose sum is the contact force the
  // state's own elastic forces imply.
  double reported_residual = std::nan(""), implied_residual = std::nan(""), implied_force = std::nan("");
  // The inner wall's displacement against each reference field asked for (run's `fields`, in order): the relative
  // L2 error over the wall (engine::wall_field_error).
  std::vector<double> field_err;
  engine::StageSummary total, physics, collision, response, render;
  long over_budget = 0, not_converged = 0, fallbacks = 0, failures = 0, max_inverted = 0;
  int nodes = 0, tets = 0, inner_tris = 0;
  double compile_s = 0, session_s = 0;
};

constexpr double kInnerRadius = 0.01;   // metres, the tube's (the paper's organ)
constexpr double kOuterRadius = 0.013;  // metres
constexpr double kCapacityFps = 40.0;   // the capacity sweep's frame rate: its budget is 1000 / fps ms
constexpr double kProbeZ = 0.05;        // metres, mid-length
constexpr double kPatchRadius = 0.003;  // metres: the probe tip's radius; its displacement is averaged over it
constexpr double kPi = static_cast<double>(EIGEN_PI);  // Eigen's constant, a long double, as a double

// A mesh level's name, "around x along x layers" (the sweeps' --reference-mesh, --closure-mesh).
std::string mesh_name(const Level& l) {
  return std::to_string(l.around) + "x" + std::to_string(l.along) + "x" + std::to_string(l.layers);
}

// The configuration's solver settings on a scene (the tolerance and the work bound only matter to the corotational
// solve).
void apply_solver(engine::Scene& s, const Config& c) {
  if (c.model == "corotational") {
    s.solver.tolerance = c.tolerance;
    s.solver.max_iterations = c.tolerance < 1e-4 ? 40 : 20;
    s.solver.max_back_substitutions = c.max_back_substitutions;
  }
}

// The squeeze scene at a level: two probes pinch the tube at mid-length, one on the top of the outer wall
// pressing down (-y), one on the bottom pressing up, each with `force` newtons ramped over 1 s then held (no
// net load: the tube ovalises and shuts instead of bending as a beam). Each probe tip is a disk of radius
// kPatchRadius: 7 points (its centre, and 6 on its rim, on the outer wall) each carrying a seventh of the force,
// so that the load is the same on every mesh (a load on one triangle shrinks with the mesh: a point load, whose
// displacement does not converge). probes[0] is the top tip's centre.
engine::Scene squeeze_scene(const Config& c, double force, int frames, double fps) {
  engine::Scene s;
  s.path = "<study>";
  s.name = "study-squeeze";
  s.mesh.inner_radius = kInnerRadius;
  s.mesh.outer_radius = kOuterRadius;
  s.mesh.length = 0.1;
  s.mesh.segments_around = c.level.around;
  s.mesh.segments_along = c.level.along;
  s.mesh.layers = c.level.layers;
  s.element = c.element == "tet10" ? engine::ElementType::kTet10 : engine::ElementType::kTet4;
  s.material.model = c.model == "corotational" ? engine::MaterialModel::kCorotational : engine::MaterialModel::kLinear;
  s.material.young_modulus = 5000.0;
  s.material.poisson_ratio = 0.45;
  s.fixed = {engine::NodeSetName::kEnds};
  if (c.grade_around != 1.0) s.mesh.grading_around = {{kPi / 2.0, 1.5 * kPi}, c.grade_around};
  if (c.grade_along != 1.0) s.mesh.grading_along = {{kProbeZ}, c.grade_along};
  // Tip points sit at the mean radius of the faceted outer wall (between its corners and its facets' middles;
  // a quadratic wall is drawn with twice the facets, over its corner and edge nodes), the facets at the tip.
  const physics::CylinderGrid grid = physics::hollow_cylinder_grid(s.mesh);
  const int tip_cell = c.level.around / 4;
  const double facet = (grid.angle[tip_cell + 1] - grid.angle[tip_cell]) / (c.element == "tet10" ? 2 : 1);
  const double r = s.mesh.outer_radius * 0.5 * (1.0 + std::cos(0.5 * facet));
  constexpr double kGoldenAngle = 2.399963229728653;  // radians, pi (3 - sqrt 5)
  for (int side = 0; side < 2; ++side) {
    const double sign = side == 0 ? 1.0 : -1.0;  // top tip: +y, pressing -y; bottom tip: -y, pressing +y
    for (int k = 0; k < c.tip_points; ++k) {
      // Tip point k, as an arc along the wall and an axial offset: 7 points: the centre (k = 0) or the rim at
      // 60-degree steps; otherwise an equal-area (sunflower) spiral over the disk, each point a 1 / n of its area.
      double arc = 0.0, dz = 0.0;
      if (c.tip_points == 7) {
        arc = k == 0 ? 0.0 : kPatchRadius * std::cos(kPi / 3.0 * (k - 1));
        dz = k == 0 ? 0.0 : kPatchRadius * std::sin(kPi / 3.0 * (k - 1));
      } else {
        const double rho = kPatchRadius * std::sqrt((k + 0.5) / c.tip_points), phi = kGoldenAngle * k;
        arc = rho * std::cos(phi);
        dz = rho * std::sin(phi);
      }
      const double angle = kPi / 2.0 - arc / r;
      engine::ProbeSpec p;
      p.name = (side == 0 ? "top" : "bottom") + std::to_string(k);
      p.point = {r * std::cos(angle), sign * r * std::sin(angle), kProbeZ + dz};
      const double share = force / c.tip_points;
      p.track = {{0.0, {0, 0, 0}}, {1.0, {0, -sign * share, 0}}, {1e3, {0, -sign * share, 0}}};
      s.probes.push_back(p);
    }
  }
  s.frames = frames;
  s.fps = fps;
  s.render.width = 640;
  s.render.height = 480;
  s.render.camera = render::CameraPreset::Side;
  s.collision.self = true;
  apply_solver(s, c);
  return s;
}

// A reference field over the inner wall and the factor on its displacement (a linear reference at another force).
struct FieldAt {
  const engine::WallField* field;
  double scale;
};

// Runs a scene (rendering off-screen when `render`) and measures the last frame's shape, and its inner wall against
// the `fields`.
Outcome run(const engine::Scene& scene, bool render, const std::vector<FieldAt>& fields = {}) {
  Outcome o;
  const auto t0 = std::chrono::steady_clock::now();
  auto model = engine::compile_model(scene);
  o.compile_s = model->compile_seconds;
  const physics::TetMesh& mesh = model->mesh;
  o.nodes = mesh.n_nodes();
  o.tets = model->n_elements;  // (tet10: the quadratic elements, not the 8 linear tets of each in mesh.tets)
  o.inner_tris = static_cast<int>(mesh.surface(lumen::physics::kInnerWall).rows());
  const auto& ms = scene.mesh;

  // Outer-wall nodes of the probe patch (rest positions within kPatchRadius of the first probe's point).
  std::vector<int> patch;
  std::vector<char> on_outer(mesh.n_nodes(), 0);
  for (int t = 0; t < mesh.surface(lumen::physics::kOuterWall).rows(); ++t)
    for (int k = 0; k < 3; ++k) on_outer[mesh.surface(lumen::physics::kOuterWall)(t, k)] = 1;
  for (int v = 0; v < mesh.n_nodes(); ++v)
    if (on_outer[v] && (mesh.rest.row(v).transpose() - scene.probes[0].point).norm() <= kPatchRadius) patch.push_back(v);
  // Inner-wall nodes facing each other at the probes' section: ring along/2, layer 0, angles 90 and 270 degrees.
  const int ring = ms.segments_along / 2;
  const int top = (ring * (ms.layers + 1)) * ms.segments_around + ms.segments_around / 4;
  const int bottom = (ring * (ms.layers + 1)) * ms.segments_around + 3 * ms.segments_around / 4;
  // Inner-wall area per node (a third of each incident triangle's rest area), m^2.
  const Eigen::VectorXd node_area = lumen::physics::lumped_areas(mesh.rest, mesh.surface(lumen::physics::kInnerWall));

  // The session, measuring the committed state after the last frame.
  engine::SessionOptions opt;
  opt.render = render;
  opt.write_frames = false;
  opt.on_end = [&](const engine::Model& m, const engine::State& st, const engine::FrameRecord& rec) {
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (int v : patch) mean += st.sim.u.segment<3>(3 * v);
    o.probe_disp = patch.empty() ? 0.0 : (mean / static_cast<double>(patch.size())).norm();
    // The top tip's load points (the first half of the probes): their mean displacement along the pinch.
    const size_t per_tip = m.probe_points.size() / 2;
    double along_pinch = 0.0;
    for (size_t p = 0; p < per_tip; ++p)
      along_pinch -= (engine::point_of(st.x, m.probe_points[p]) - engine::point_of(m.mesh.rest, m.probe_points[p])).y();
    o.tip_mean = along_pinch / static_cast<double>(per_tip);
    o.opening = (st.x.row(top) - st.x.row(bottom)).norm();
    o.contact_area = 0.0;
    for (int v = 0; v < m.mesh.n_nodes(); ++v)
      if (st.in_contact[v]) o.contact_area += node_area[v];
    o.contact_force = rec.contact_force;
    for (const FieldAt& f : fields)
      o.field_err.push_back(
          engine::wall_field_error(m.mesh.rest, m.mesh.surface(lumen::physics::kInnerWall), st.sim.u, *f.field, f.scale)
              .relative_l2);
    const engine::ContactEquilibrium eq = engine::contact_equilibrium(m, st);
    if (eq.available) {
      o.reported_residual = eq.reported_residual;
      o.implied_residual = eq.fitted_residual;
      o.implied_force = eq.fitted_force;
    }
  };
  const engine::SessionResult r = engine::run_session(*model, engine::make_inputs(scene), opt);
  o.session_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  // Frame statistics.
  std::vector<double> col[5];
  for (const engine::FrameRecord& f : r.frames) {
    col[0].push_back(f.ms[engine::kTotal]);
    col[1].push_back(f.ms[engine::kPhysics]);
    col[2].push_back(f.ms[engine::kCollision]);
    col[3].push_back(f.ms[engine::kResponse]);
    col[4].push_back(f.ms[engine::kRender]);
    o.over_budget += f.over_budget;
    o.not_converged += !f.physics_converged;
    o.fallbacks += f.fallback;
    o.failures += f.numerical_failure;
    o.max_inverted = std::max<long>(o.max_inverted, f.inverted_elements);
  }
  o.total = engine::summarize(col[0]);
  o.physics = engine::summarize(col[1]);
  o.collision = engine::summarize(col[2]);
  o.response = engine::summarize(col[3]);
  o.render = engine::summarize(col[4]);
  return o;
}

// Relative error of value against ref; against a zero reference: 0 when value is 0 too, else 1 (all wrong).
double rel(double value, double ref) {
  if (ref == 0.0) return value == 0.0 ? 0.0 : 1.0;
  return std::abs(value - ref) / std::abs(ref);
}

// The study's command-line options.
struct StudyOptions {
  std::string out = "study.csv", load_out, capacity_out;
  int capacity_frames = 60;
  bool capacity_only = false;
  int frames = 30, max_level = 99;
  double fps = 20.0;
  bool quick = false, no_render = false;
  int max_corotational_tets = 30000;
  std::string reference_csv, reference_out;  // the CalculiX reference sweep (both set) or none
  std::string closure_out;                    // the sweep past closure against the reference's contact rows
  std::string coupling = "correct";           // the closure sweep's corotational coupling: "correct" | "carried"
  std::string closure_models = "all";         // the closure sweep's models: "linear" | "corotational" | "all"
  std::string closure_mesh;                   // the closure sweep's one mesh ("24x14x1"; empty: all)
  // The reference's inner-wall displacement fields (tools/reference/ccx_reference.py's reference_inner_wall CSVs, 3 mm
  // tips): linear (at any force: scaled), Neo-Hookean NLGEOM (compared at its force), past closure (at its force);
  // empty: no full-field error.
  std::string field_linear, field_neohooke, field_closure;
  double closure_force = 0.03;                // the closure sweep's force per tip, newtons (a reference row's)
  std::string reference_meshes = "all";       // the reference sweep's meshes: "uniform" | "graded" | "all"
  std::string reference_mesh;                 // the reference sweep's one mesh ("24x14x1"; empty: all)
  std::string reference_models = "all";       // the reference sweep's models: "linear" | "corotational" | "all"
  int max_back_substitutions = 0;             // the reference sweep's corotational work bound (0: none)
  std::string capacity_scenario = "all";      // the capacity sweep's scenarios: "open" | "shut" | "all"
  std::string capacity_family = "all";        // its families: "tet4-linear" | "tet4-corotational" | "tet10-linear"
  int capacity_min_tets = 0;                  // its meshes from this many elements on (the smaller are skipped)
};

// Two opposite probes at 1.25x the force that first shuts the lumen (0.08 N on the paper mesh, linear): the walls
// pressed together over an area.
constexpr double kShutForce = 0.1;

// The error sweep: every configuration against the reference (the finest level, corotational, tight tolerance),
// small deformation against Lame's solution; one CSV row per configuration, written as it grows.
void error_sweep(const StudyOptions& opt, const std::vector<Level>& levels, const std::vector<Level>& quadratic_levels,
                 const std::vector<double>& tolerances) {
  char line[1024];  // one CSV row
  const Level finest = levels.back();
  std::fprintf(stderr, "reference: %dx%dx%d corotational 1e-5\n", finest.around, finest.along, finest.layers);
  // (quasi-static: the end state hardly depends on the increments, so the reference takes five load steps)
  const Outcome ref = run(squeeze_scene({finest, "tet4", "corotational", 1e-5}, kShutForce, 8, 5.0), false);
  std::vector<Config> configs;
  for (const Level& l : levels) {
    configs.push_back({l, "tet4", "linear", 0.0});
    if (6 * l.around * l.along * l.layers <= opt.max_corotational_tets)
      for (double tol : tolerances) configs.push_back({l, "tet4", "corotational", tol});
  }
  for (const Level& l : quadratic_levels) configs.push_back({l, "tet10", "linear", 0.0});
  std::string csv =
      "around,along,layers,nodes,tets,inner_tris,element,model,tolerance,frames,total_median_ms,total_p99_ms,"
      "physics_median_ms,physics_p99_ms,collision_median_ms,response_median_ms,render_median_ms,over_budget,"
      "not_converged,fallbacks,failures,max_inverted,lame_error,probe_disp_mm,opening_mm,contact_area_mm2,"
      "contact_force_n,err_probe_disp,err_opening,err_contact_area,err_contact_force,err_shape,err_contact,err_large,"
      "compile_s\n";
  for (const Config& c : configs) {
    std::fprintf(stderr, "%dx%dx%d %s %s %g ...", c.level.around, c.level.along, c.level.layers, c.element.c_str(),
                 c.model.c_str(), c.tolerance);
    // Small deformation: Lame plane strain at this cross-section resolution.
    physics::LameSetup lame;
    lame.segments_around = c.level.around;
    lame.segments_along = 2;
    lame.layers = c.level.layers;
    lame.material = {5000.0, 0.45};
    lame.element = c.element == "tet10" ? physics::ElementOrder::kQuadratic : physics::ElementOrder::kLinear;
    const double lame_err = physics::lame_error(lame).rel_l2_error;
    // Large deformation with contact, timed with rendering.
    const Outcome o = run(squeeze_scene(c, kShutForce, opt.frames, opt.fps), !opt.no_render);
    const double e_probe = rel(o.probe_disp, ref.probe_disp);
    const double e_open = std::abs(o.opening - ref.opening) / (2.0 * kInnerRadius);  // relative to the rest diameter
    const double e_area = rel(o.contact_area, ref.contact_area);
    const double e_force = rel(o.contact_force, ref.contact_force);
    const double e_shape = std::max(e_probe, e_open), e_contact = std::max(e_area, e_force);
    const double e_large = std::max(e_shape, e_contact);
    std::snprintf(line, sizeof line,
                  "%d,%d,%d,%d,%d,%d,%s,%s,%g,%d,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%ld,%ld,%ld,%ld,%ld,"
                  "%.6g,%.6g,%.6g,"
                  "%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.3f\n",
                  c.level.around, c.level.along, c.level.layers, o.nodes, o.tets, o.inner_tris, c.element.c_str(),
                  c.model.c_str(), c.tolerance, opt.frames, o.total.median_ms, o.total.p99_ms, o.physics.median_ms,
                  o.physics.p99_ms, o.collision.median_ms, o.response.median_ms, o.render.median_ms, o.over_budget,
                  o.not_converged, o.fallbacks, o.failures, o.max_inverted, lame_err, 1e3 * o.probe_disp,
                  1e3 * o.opening, 1e6 * o.contact_area, o.contact_force, e_probe, e_open, e_area, e_force, e_shape,
                  e_contact, e_large, o.compile_s);
    csv += line;
    engine::write_text_file(opt.out, csv);  // after every configuration, so a long sweep can be read while it runs
    std::fprintf(stderr, " total %.2f / %.2f ms, lame %.4f, shape %.4f, contact %.4f\n", o.total.median_ms,
                 o.total.p99_ms, lame_err, e_shape, e_contact);
  }
}

// Load sweep on the paper mesh: the pinch, linear against corotational.
void load_sweep(const StudyOptions& opt) {
  char line[1024];
  std::string lcsv = "force_n,linear_probe_disp_mm,corotational_probe_disp_mm,relative_difference,max_disp_over_wall\n";
  const Level paper{20, 26, 3};
  for (double f : {0.002, 0.005, 0.01, 0.02, 0.04, 0.06, 0.08}) {
    const Outcome lin = run(squeeze_scene({paper, "tet4", "linear", 0.0}, f, 15, 10.0), false);
    const Outcome cor = run(squeeze_scene({paper, "tet4", "corotational", 1e-6}, f, 15, 10.0), false);
    std::snprintf(line, sizeof line, "%g,%.6g,%.6g,%.6g,%.6g\n", f, 1e3 * lin.probe_disp, 1e3 * cor.probe_disp,
                  rel(lin.probe_disp, cor.probe_disp), cor.probe_disp / (kOuterRadius - kInnerRadius));
    lcsv += line;
    std::fprintf(stderr, "load %g N: linear %.3f mm, corotational %.3f mm\n", f, 1e3 * lin.probe_disp,
                 1e3 * cor.probe_disp);
  }
  engine::write_text_file(opt.load_out, lcsv);
}

// The converged CalculiX tip displacement of one case (tools/reference/ccx_reference.py's CSV): per (force,
// material) the finest level that finished ("ok").
struct ReferenceTip {
  double tip_m = 0.0;  // area-weighted mean over the tip's disc of the displacement along the pinch, metres
  int dofs = 0;
  // Past closure (rows with contact; NaN where the row has none): the full tube's contact force between the
  // upper and lower inner wall (newtons), its contact area on one side (m^2), the lumen's opening under the tips
  // (metres, <= 0 closed).
  double contact_force_n = std::nan(""), contact_area_m2 = std::nan(""), opening_m = std::nan("");
};
using ReferenceTable = std::map<std::pair<double, std::string>, ReferenceTip>;

// Reads the reference CSV (comment lines start with '#'); throws std::runtime_error naming the file and the line.
ReferenceTable read_reference(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot be read");
  ReferenceTable table;
  std::string line;
  std::vector<std::string> header;
  for (int number = 1; std::getline(in, line); ++number) {
    if (line.empty() || line[0] == '#') continue;
    std::vector<std::string> cells;
    std::stringstream ss(line);
    for (std::string cell; std::getline(ss, cell, ',');) cells.push_back(cell);
    if (header.empty()) {
      header = cells;
      continue;
    }
    std::map<std::string, std::string> row;
    for (size_t i = 0; i < header.size() && i < cells.size(); ++i) row[header[i]] = cells[i];
    if (row["status"] != "ok" || row["tip_displacement_m"].empty()) continue;
    try {
      const std::pair<double, std::string> key{std::stod(row["force_N"]), row["material"]};
      ReferenceTip tip{std::stod(row["tip_displacement_m"]), std::stoi(row["dofs"])};
      if (!row["contact_force_N"].empty()) tip.contact_force_n = std::stod(row["contact_force_N"]);
      if (!row["contact_area_m2"].empty()) tip.contact_area_m2 = std::stod(row["contact_area_m2"]);
      if (!row["opening_m"].empty()) tip.opening_m = std::stod(row["opening_m"]);
      if (tip.dofs > table[key].dofs) table[key] = tip;
    } catch (const std::exception&) {
      throw std::runtime_error(path + ":" + std::to_string(number) +
                               ": force_N, tip_displacement_m, dofs, contact_force_N, contact_area_m2 or opening_m is "
                               "not a number");
    }
  }
  return table;
}

// The reference row of (force, material); throws naming the file when it has none that finished.
ReferenceTip find_reference(const ReferenceTable& table, const std::string& path, double force, const char* material) {
  const auto it = table.find({force, material});
  if (it == table.end())
    throw std::runtime_error(path + ": no finished row for force " + std::to_string(force) + " N, " + material);
  return it->second;
}

// Forces this close (relative) are the same load (the reference's files print 6-7 significant digits).
constexpr double kSameForce = 1e-6;
bool same_force(double a, double b) { return std::abs(a - b) <= kSameForce * std::max(std::abs(a), std::abs(b)); }

// A CSV cell of a number, 6 significant digits.
std::string csv_number(double v) {
  char cell[32];
  std::snprintf(cell, sizeof cell, "%.6g", v);
  return cell;
}

// The sweep against the converged CalculiX reference (3 mm tips, as the squeeze's): each configuration pinched
// below first contact, at 0.002 N and 0.01 N (the tip moves about a fifth and 1.6x the wall thickness), against
// two references: the linear one (small strain, no NLGEOM; computed at 0.002 N and scaled by the force, which is
// exact for it), whose difference from a linear-model configuration is that configuration's discretisation error,
// and the Neo-Hookean NLGEOM one, the physical answer, whose difference from any configuration is its whole error
// (discretisation and model). Whole-frame times with self-collision and rendering.
void reference_sweep(const StudyOptions& opt) {
  const ReferenceTable table = read_reference(opt.reference_csv);
  constexpr double kLinearReferenceForce = 0.002;  // newtons: the force of the linear reference row
  constexpr double kLargeForce = 0.01;             // newtons: the large pinch's, below first contact
  auto lookup = [&](double force, const char* material) { return find_reference(table, opt.reference_csv, force, material); };
  const ReferenceTip linear = lookup(kLinearReferenceForce, "linear");
  std::vector<Config> configs;
  auto tolerance_of = [](const char* model) { return std::string(model) == "linear" ? 0.0 : 1e-4; };
  // Uniform meshes, the tips as 7 points (the sweep of docs/study_reference.csv before grading).
  if (opt.reference_meshes != "graded") {
    for (const Level& l : std::vector<Level>{{12, 16, 2}, {20, 26, 3}, {28, 36, 4}, {40, 52, 6}})
      for (const char* model : {"linear", "corotational"})
        if (std::string(model) == "linear" || 6 * l.around * l.along * l.layers <= opt.max_corotational_tets)
          configs.push_back({l, "tet4", model, tolerance_of(model)});
    for (const Level& l : std::vector<Level>{{8, 10, 1}, {10, 13, 1}, {16, 20, 2}, {20, 26, 2}})
      for (const char* model : {"linear", "corotational"}) configs.push_back({l, "tet10", model, tolerance_of(model)});
  }
  // Graded toward the tips (the reference's own grading: 6 around, 12 along), the tips as an equal-area spiral of
  // kGradedTipPoints points, so the load approaches the reference's uniform traction on the finer cells there.
  if (opt.reference_meshes != "uniform") {
    constexpr double kGradeAround = 6.0, kGradeAlong = 12.0;
    constexpr int kGradedTipPoints = 61;
    for (const Level& l : std::vector<Level>{{24, 16, 2}, {32, 20, 3}, {48, 30, 4}})
      for (const char* model : {"linear", "corotational"})
        if (std::string(model) == "linear" || 6 * l.around * l.along * l.layers <= opt.max_corotational_tets)
          configs.push_back({l, "tet4", model, tolerance_of(model), kGradeAround, kGradeAlong, kGradedTipPoints});
    for (const Level& l : std::vector<Level>{{12, 8, 1}, {16, 10, 1}, {24, 14, 1}, {32, 20, 2}})
      for (const char* model : {"linear", "corotational"})
        configs.push_back({l, "tet10", model, tolerance_of(model), kGradeAround, kGradeAlong, kGradedTipPoints});
  }
  // The asked mesh and models only (refused when none is left), with the asked work bound.
  std::vector<Config> asked;
  for (Config c : configs) {
    if ((opt.reference_mesh.empty() || opt.reference_mesh == mesh_name(c.level)) &&
        (opt.reference_models == "all" || opt.reference_models == c.model)) {
      c.max_back_substitutions = opt.max_back_substitutions;
      asked.push_back(c);
    }
  }
  if (asked.empty())
    throw std::runtime_error("--reference-mesh, --reference-models: no configuration of the reference sweep (" +
                             opt.reference_meshes + " meshes) is mesh \"" + opt.reference_mesh + "\" with model \"" +
                             opt.reference_models + "\"");
  configs = asked;
  std::string csv =
      "force_n,reference_linear_mm,reference_neohooke_mm,reference_dofs,around,along,layers,grade_around,grade_along,"
      "tip_points,nodes,tets,element,model,tolerance,frames,probe_disp_mm,err_vs_linear,err_vs_neohooke,tip_mean_mm,"
      "tip_err_vs_linear,tip_err_vs_neohooke,total_median_ms,total_p99_ms,physics_median_ms,physics_p99_ms,"
      "over_budget,not_converged,fallbacks,failures,field_err_vs_linear,field_err_vs_neohooke,max_back_substitutions,fps\n";
  // The full-field references, read once (a missing or bad file stops the sweep before its first run).
  const engine::WallField linear_field =
      opt.field_linear.empty() ? engine::WallField{} : engine::read_wall_field(opt.field_linear);
  const engine::WallField neohooke_field =
      opt.field_neohooke.empty() ? engine::WallField{} : engine::read_wall_field(opt.field_neohooke);
  if (!opt.field_neohooke.empty() && !same_force(neohooke_field.force_n, kLinearReferenceForce) &&
      !same_force(neohooke_field.force_n, kLargeForce))
    throw std::runtime_error(opt.field_neohooke + ": its force is " + csv_number(neohooke_field.force_n) +
                             " N, neither of the sweep's (" + csv_number(kLinearReferenceForce) + ", " +
                             csv_number(kLargeForce) + " N)");
  char line[1024];  // one CSV row
  for (double force : {kLinearReferenceForce, kLargeForce}) {
    const ReferenceTip neohooke = lookup(force, "neohooke");
    const double linear_tip = linear.tip_m * force / kLinearReferenceForce;
    for (const Config& c : configs) {
      std::fprintf(stderr, "%g N %dx%dx%d %s %s ...", force, c.level.around, c.level.along, c.level.layers,
                   c.element.c_str(), c.model.c_str());
      // The fields at this force: the linear one scaled to it, the Neo-Hookean one at its own force only.
      std::vector<FieldAt> fields;
      int linear_at = -1, neohooke_at = -1;
      if (!opt.field_linear.empty()) {
        linear_at = static_cast<int>(fields.size());
        fields.push_back({&linear_field, force / linear_field.force_n});
      }
      if (!opt.field_neohooke.empty() && same_force(neohooke_field.force_n, force)) {
        neohooke_at = static_cast<int>(fields.size());
        fields.push_back({&neohooke_field, 1.0});
      }
      const Outcome o = run(squeeze_scene(c, force, opt.frames, opt.fps), !opt.no_render, fields);
      const std::string field_linear = linear_at < 0 ? "" : csv_number(o.field_err[linear_at]);
      const std::string field_neohooke = neohooke_at < 0 ? "" : csv_number(o.field_err[neohooke_at]);
      // Signed relative errors: < 0 too stiff.
      const double err_linear = (o.probe_disp - linear_tip) / linear_tip;
      const double err_neohooke = (o.probe_disp - neohooke.tip_m) / neohooke.tip_m;
      const double tip_err_linear = (o.tip_mean - linear_tip) / linear_tip;
      const double tip_err_neohooke = (o.tip_mean - neohooke.tip_m) / neohooke.tip_m;
      std::snprintf(line, sizeof line,
                    "%g,%.6g,%.6g,%d,%d,%d,%d,%g,%g,%d,%d,%d,%s,%s,%g,%d,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.4f,%.4f,%.4f,"
                    "%.4f,%ld,%ld,%ld,%ld,%s,%s,%d,%g\n",
                    force, 1e3 * linear_tip, 1e3 * neohooke.tip_m, neohooke.dofs, c.level.around, c.level.along,
                    c.level.layers, c.grade_around, c.grade_along, c.tip_points, o.nodes, o.tets, c.element.c_str(),
                    c.model.c_str(), c.tolerance, opt.frames, 1e3 * o.probe_disp, err_linear, err_neohooke,
                    1e3 * o.tip_mean, tip_err_linear, tip_err_neohooke, o.total.median_ms, o.total.p99_ms,
                    o.physics.median_ms, o.physics.p99_ms, o.over_budget, o.not_converged, o.fallbacks, o.failures,
                    field_linear.c_str(), field_neohooke.c_str(), c.model == "corotational" ? c.max_back_substitutions : 0,
                    opt.fps);
      csv += line;
      engine::write_text_file(opt.reference_out, csv);  // after every configuration
      std::fprintf(stderr,
                   " patch %.4f mm (%+.1f %% vs linear, %+.1f %% vs Neo-Hookean), load points %.4f mm (%+.1f %%, "
                   "%+.1f %%), total %.2f / %.2f ms (physics %.2f / %.2f, collision %.2f, response %.2f, render %.2f "
                   "median), %ld unconverged; inner wall L2 %s vs linear, %s vs Neo-Hookean\n",
                   1e3 * o.probe_disp, 100.0 * err_linear, 100.0 * err_neohooke, 1e3 * o.tip_mean,
                   100.0 * tip_err_linear, 100.0 * tip_err_neohooke, o.total.median_ms, o.total.p99_ms,
                   o.physics.median_ms, o.physics.p99_ms, o.collision.median_ms, o.response.median_ms,
                   o.render.median_ms, o.not_converged, field_linear.c_str(), field_neohooke.c_str());
    }
  }
}

// Past closure against the CalculiX contact reference (--closure-out): the same two 3 mm tips at --closure-force
// each (default 0.03 N: 1.4x the force at which the reference's walls first touch, 0.021 N, so that the inner walls
// are pressed together over an area; at 0.02 N, just before they touch, the tip and the opening that lead to the
// contact; --closure-mesh runs one mesh); the reference is the Neo-Hookean NLGEOM quarter tube with a frictionless
// penalty contact pair between the upper and lower inner wall (material "neohooke-pair"). Compared at the last
// frame: the top tip's load-point mean along the pinch (the reference's work-conjugate tip mean), the opening, the
// total contact force the walls carry (Lumen: the sum of the contact multipliers; the reference: the normal force
// on its slave side), and the contact area on one side (Lumen: half the inner-wall area of the nodes in contact,
// both walls' nodes being marked; the reference: its slave side's contact area, which depends on the penalty: 27 %
// less at 10x it).
// The reference's tip is converged to 0.3 %, its contact force only to 14 % (levels 2 -> 3).
void closure_sweep(const StudyOptions& opt) {
  const double force = opt.closure_force;  // newtons per tip
  const ReferenceTip ref =
      find_reference(read_reference(opt.reference_csv), opt.reference_csv, force, "neohooke-pair");
  if (std::isnan(ref.contact_force_n) || std::isnan(ref.contact_area_m2))
    throw std::runtime_error(opt.reference_csv + ": the neohooke-pair row at " + std::to_string(force) +
                             " N has no contact_force_N or contact_area_m2");
  constexpr double kGradeAround = 6.0, kGradeAlong = 12.0;
  constexpr int kGradedTipPoints = 61;
  // The sweep's meshes (uniform, then graded toward the tips); the configurations of the asked models on the asked
  // mesh (refused when it is none of the sweep's).
  const std::vector<Config> meshes = {{{20, 26, 3}, "tet4", "", 0.0},
                                      {{10, 13, 1}, "tet10", "", 0.0},
                                      {{24, 14, 1}, "tet10", "", 0.0, kGradeAround, kGradeAlong, kGradedTipPoints},
                                      {{32, 20, 2}, "tet10", "", 0.0, kGradeAround, kGradeAlong, kGradedTipPoints}};
  std::vector<Config> configs;
  for (const char* model : {"linear", "corotational"}) {
    if (opt.closure_models != "all" && opt.closure_models != model) continue;
    for (Config c : meshes) {
      if (!opt.closure_mesh.empty() && opt.closure_mesh != mesh_name(c.level)) continue;
      c.model = model;
      c.tolerance = c.model == "linear" ? 0.0 : 1e-4;
      configs.push_back(c);
    }
  }
  if (configs.empty()) {
    std::string names;
    for (const Config& c : meshes) names += (names.empty() ? "" : ", ") + mesh_name(c.level);
    throw std::runtime_error("--closure-mesh: names no mesh of the closure sweep (" + names + ") (value \"" +
                             opt.closure_mesh + "\")");
  }
  std::string csv =
      "force_n,reference_tip_mm,reference_contact_force_n,reference_contact_area_mm2,reference_dofs,around,along,"
      "layers,grade_around,grade_along,tip_points,nodes,tets,element,model,coupling,tolerance,frames,tip_mean_mm,"
      "tip_err,opening_mm,reference_opening_mm,contact_force_n,contact_force_err,contact_area_mm2,contact_area_err,"
      "total_median_ms,total_p99_ms,physics_median_ms,physics_p99_ms,response_median_ms,response_p99_ms,over_budget,"
      "not_converged,fallbacks,failures,max_inverted,reported_residual,implied_contact_force_n,implied_residual,"
      "field_err\n";
  // The reference's inner wall past closure, compared at its own force only (refused at another).
  const engine::WallField closure_field =
      opt.field_closure.empty() ? engine::WallField{} : engine::read_wall_field(opt.field_closure);
  if (!opt.field_closure.empty() && !same_force(closure_field.force_n, force))
    throw std::runtime_error(opt.field_closure + ": its force is " + csv_number(closure_field.force_n) +
                             " N, not the closure sweep's " + csv_number(force) + " N (--closure-force)");
  std::vector<FieldAt> fields;
  if (!opt.field_closure.empty()) fields.push_back({&closure_field, 1.0});
  char line[1024];  // one CSV row
  for (const Config& c : configs) {
    std::fprintf(stderr, "closure %g N %s %s %s ...", force, mesh_name(c.level).c_str(), c.element.c_str(),
                 c.model.c_str());
    engine::Scene scene = squeeze_scene(c, force, opt.frames, opt.fps);
    if (c.model == "corotational" && opt.coupling == "carried")
      scene.collision.coupling = engine::ContactCoupling::kCarried;
    const char* coupling = c.model == "corotational" ? opt.coupling.c_str() : "";
    const Outcome o = run(scene, !opt.no_render, fields);
    const std::string field_err = fields.empty() ? "" : csv_number(o.field_err[0]);
    const double area_one_side = 0.5 * o.contact_area;
    // Signed relative errors: < 0 too stiff (tip), too little force or area.
    const double tip_err = (o.tip_mean - ref.tip_m) / ref.tip_m;
    const double force_err = (o.contact_force - ref.contact_force_n) / ref.contact_force_n;
    const double area_err = (area_one_side - ref.contact_area_m2) / ref.contact_area_m2;
    std::snprintf(line, sizeof line,
                  "%g,%.6g,%.6g,%.6g,%d,%d,%d,%d,%g,%g,%d,%d,%d,%s,%s,%s,%g,%d,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,"
                  "%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%ld,%ld,%ld,%ld,%ld,%.6g,%.6g,%.6g,%s\n",
                  force, 1e3 * ref.tip_m, ref.contact_force_n, 1e6 * ref.contact_area_m2, ref.dofs,
                  c.level.around, c.level.along, c.level.layers, c.grade_around, c.grade_along, c.tip_points, o.nodes,
                  o.tets, c.element.c_str(), c.model.c_str(), coupling, c.tolerance, opt.frames, 1e3 * o.tip_mean,
                  tip_err, 1e3 * o.opening, 1e3 * ref.opening_m, o.contact_force, force_err, 1e6 * area_one_side,
                  area_err, o.total.median_ms, o.total.p99_ms, o.physics.median_ms, o.physics.p99_ms,
                  o.response.median_ms, o.response.p99_ms, o.over_budget, o.not_converged, o.fallbacks, o.failures,
                  o.max_inverted, o.reported_residual, o.implied_force, o.implied_residual, field_err.c_str());
    csv += line;
    engine::write_text_file(opt.closure_out, csv);  // after every configuration
    std::fprintf(stderr,
                 " tip %.3f mm (%+.1f %%), opening %.3f mm (reference %.3f), contact force %.2f mN (%+.1f %%), "
                 "area %.2f mm^2 (%+.1f %%), total %.1f / %.1f ms, fallbacks %ld; equilibrium residual %.3g "
                 "reported, %.3g fitted, fitted force %.2f mN; inner wall L2 %s\n",
                 1e3 * o.tip_mean, 100.0 * tip_err, 1e3 * o.opening, 1e3 * ref.opening_m, 1e3 * o.contact_force,
                 100.0 * force_err, 1e6 * area_one_side, 100.0 * area_err, o.total.median_ms, o.total.p99_ms,
                 o.fallbacks, o.reported_residual, o.implied_residual, 1e3 * o.implied_force, field_err.c_str());
  }
}

// A model family of the capacity sweep.
struct Family {
  const char* element;
  const char* model;
  double tolerance;
  Level base;  // scale 1 (the paper's tube: 20 x 26 x 3 linear cells, 10 x 13 x 1 quadratic ones)
  int min_layers;
};

// One family's meshes growing by about 1.4x in tets (linear scale steps of 2^(1/6)) until the frame's p99 exceeds
// the budget; one CSV row per mesh appended to ccsv (written as it grows).
void capacity_family(const StudyOptions& opt, const char* scenario, double load, const Family& fam, std::string& ccsv) {
  char line[1024];
  Level previous{0, 0, 0};
  for (int step = -6; step <= 18; ++step) {
    const double scale = std::pow(2.0, step / 6.0);
    const Level l{std::max(6, static_cast<int>(std::lround(fam.base.around * scale))),
                  std::max(6, static_cast<int>(std::lround(fam.base.along * scale))),
                  std::max(fam.min_layers, static_cast<int>(std::lround(fam.base.layers * scale)))};
    if (l.around == previous.around && l.along == previous.along && l.layers == previous.layers) continue;
    previous = l;
    const Config c{l, fam.element, fam.model, fam.tolerance};
    // (a tet10 cell holds 6 quadratic tets, as a tet4 cell 6 linear ones)
    if (6L * l.around * l.along * l.layers < opt.capacity_min_tets) continue;
    std::fprintf(stderr, "capacity %s %s %s %dx%dx%d ...", scenario, fam.element, fam.model, l.around, l.along,
                 l.layers);
    Outcome o;
    try {
      o = run(squeeze_scene(c, load, opt.capacity_frames, kCapacityFps), true);
    } catch (const std::exception& e) {
      // (a mesh this family cannot build or load: reported, and the family ends here)
      std::fprintf(stderr, " skipped: %s\n", e.what());
      return;
    }
    const bool within = o.total.p99_ms <= 1000.0 / kCapacityFps;
    std::snprintf(line, sizeof line, "%s,%g,%s,%s,%g,%d,%d,%d,%d,%d,%d,%d,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%ld,%d\n",
                  scenario, load, fam.element, fam.model, fam.tolerance, l.around, l.along, l.layers, o.nodes, o.tets,
                  o.inner_tris, opt.capacity_frames, o.total.median_ms, o.total.p99_ms, o.physics.median_ms,
                  o.physics.p99_ms, o.collision.median_ms, o.response.median_ms, o.render.median_ms, o.over_budget,
                  within ? 1 : 0);
    ccsv += line;
    engine::write_text_file(opt.capacity_out, ccsv);
    std::fprintf(stderr, " %d tets, total %.2f / p99 %.2f ms\n", o.tets, o.total.median_ms, o.total.p99_ms);
    if (!within) return;
  }
}

// Capacity: per model, the largest mesh within the budget, lumen open and shut.
void capacity_sweep(const StudyOptions& opt) {
  std::string ccsv =
      "scenario,force_n,element,model,tolerance,around,along,layers,nodes,tets,inner_tris,frames,total_median_ms,"
      "total_p99_ms,"
      "physics_median_ms,physics_p99_ms,collision_median_ms,response_median_ms,render_median_ms,over_budget,"
      "within_budget\n";
  const Family families[] = {{"tet4", "linear", 0.0, {20, 26, 3}, 2},
                             {"tet4", "corotational", 1e-3, {20, 26, 3}, 2},
                             {"tet10", "linear", 0.0, {10, 13, 1}, 1}};
  const std::pair<const char*, double> scenarios[] = {{"open", 0.02}, {"shut", kShutForce}};
  for (const auto& [scenario, load] : scenarios)
    for (const Family& fam : families) {
      const bool wanted = (opt.capacity_scenario == "all" || opt.capacity_scenario == scenario) &&
                          (opt.capacity_family == "all" ||
                           opt.capacity_family == std::string(fam.element) + "-" + fam.model);
      if (wanted) capacity_family(opt, scenario, load, fam, ccsv);
    }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Lumen speed-against-error study"};
  StudyOptions opt;
  app.add_option("--out", opt.out, "CSV of the sweep");
  app.add_option("--load-out", opt.load_out, "CSV of the load sweep (linear vs corotational), empty: skip");
  app.add_option("--capacity-out", opt.capacity_out,
                 "CSV of the capacity sweep (largest mesh within the 25 ms budget at p99, per model), empty: skip");
  app.add_option("--capacity-frames", opt.capacity_frames, "frames per capacity session at 40 fps")
      ->check(CLI::Range(41, 100000));
  app.add_flag("--capacity-only", opt.capacity_only, "run only the capacity sweep");
  app.add_option("--capacity-scenario", opt.capacity_scenario, "the capacity sweep's scenarios")
      ->check(CLI::IsMember({"open", "shut", "all"}));
  app.add_option("--capacity-family", opt.capacity_family, "the capacity sweep's model families")
      ->check(CLI::IsMember({"tet4-linear", "tet4-corotational", "tet10-linear", "all"}));
  app.add_option("--capacity-min-tets", opt.capacity_min_tets,
                 "the capacity sweep's meshes from this many elements on (to measure one large mesh); with any of "
                 "these filters --capacity-out holds only the rows they ran")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--frames", opt.frames, "frames per session (the squeeze ramps over 1 s)")->check(CLI::Range(2, 100000));
  app.add_option("--fps", opt.fps, "simulated frames per second (quasi-static: sets the load increment per frame)")
      ->check(CLI::Range(1.0, 1000.0));
  app.add_option("--max-level", opt.max_level, "finest mesh level index to run (0 = coarsest)")->check(CLI::Range(0, 99));
  app.add_option("--max-corotational-tets", opt.max_corotational_tets,
                 "skip corotational configurations above this many tets (seconds per frame there)");
  app.add_flag("--quick", opt.quick, "coarse levels only and fewer configurations (a smoke run)");
  app.add_flag("--no-render", opt.no_render, "leave rendering out of the frame time");
  app.add_option("--reference", opt.reference_csv,
                 "CalculiX reference CSV (3 mm tips) for the reference sweep, e.g. docs/reference_convergence_tip3mm.csv");
  app.add_option("--reference-out", opt.reference_out, "CSV of the sweep against the CalculiX reference; runs only it");
  app.add_option("--closure-out", opt.closure_out,
                 "CSV of the sweep past closure against the reference's contact rows (needs --reference); runs only it");
  app.add_option("--coupling", opt.coupling, "the closure sweep's corotational contact coupling (collision.coupling)")
      ->check(CLI::IsMember({"correct", "carried"}));
  app.add_option("--closure-force", opt.closure_force, "the closure sweep's force per tip, N (default 0.03)");
  app.add_option("--closure-mesh", opt.closure_mesh, "the closure sweep's one mesh, e.g. 24x14x1 (default: all)");
  app.add_option("--closure-models", opt.closure_models, "the closure sweep's models")
      ->check(CLI::IsMember({"linear", "corotational", "all"}));
  app.add_option("--field-linear", opt.field_linear,
                 "the linear reference's inner wall (reference_inner_wall CSV), scaled to each force: the reference "
                 "sweep's full-field error against it");
  app.add_option("--field-neohooke", opt.field_neohooke,
                 "the Neo-Hookean reference's inner wall, compared at its force by the reference sweep");
  app.add_option("--field-closure", opt.field_closure,
                 "the contact reference's inner wall, compared by the closure sweep (at its force only)");
  app.add_option("--reference-mesh", opt.reference_mesh, "the reference sweep's one mesh, e.g. 24x14x1 (default: all)");
  app.add_option("--reference-models", opt.reference_models, "the reference sweep's models")
      ->check(CLI::IsMember({"linear", "corotational", "all"}));
  app.add_option("--max-back-substitutions", opt.max_back_substitutions,
                 "the reference sweep's corotational work bound a frame (solver.max_back_substitutions; 0: none)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--reference-meshes", opt.reference_meshes, "the reference sweep's meshes")
      ->check(CLI::IsMember({"uniform", "graded", "all"}));
  CLI11_PARSE(app, argc, argv);
  if (opt.max_back_substitutions == 1) {
    std::fprintf(stderr, "lumen_study: --max-back-substitutions must be 0 (no bound) or >= 2 (a PCG step takes two)\n");
    return 2;
  }
  // Options of a sweep that is not asked for are refused (they would be ignored).
  const bool reference_only = !opt.field_linear.empty() || !opt.field_neohooke.empty() || !opt.reference_mesh.empty() ||
                              opt.reference_models != "all" || opt.max_back_substitutions != 0;
  if (reference_only && opt.reference_out.empty()) {
    std::fprintf(stderr, "lumen_study: --field-linear, --field-neohooke, --reference-mesh, --reference-models and "
                         "--max-back-substitutions go with --reference-out\n");
    return 2;
  }
  if (!opt.field_closure.empty() && opt.closure_out.empty()) {
    std::fprintf(stderr, "lumen_study: --field-closure goes with --closure-out\n");
    return 2;
  }
  if (opt.reference_csv.empty() != (opt.reference_out.empty() && opt.closure_out.empty())) {
    std::fprintf(stderr, "lumen_study: --reference goes with --reference-out or --closure-out\n");
    return 2;
  }
  // Output folders exist before any work (each CSV is then written atomically as it grows).
  for (const std::string& path : {opt.out, opt.load_out, opt.capacity_out, opt.reference_out, opt.closure_out})
    if (!path.empty() && fs::path(path).has_parent_path()) fs::create_directories(fs::path(path).parent_path());
  if (!opt.reference_csv.empty()) {
    try {
      if (!opt.reference_out.empty()) reference_sweep(opt);
      if (!opt.closure_out.empty()) closure_sweep(opt);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "lumen_study: %s\n", e.what());
      return 2;
    }
    return 0;
  }

  // Mesh levels: coarser than the paper, the paper (9360 tets), then up to 8x its tets. Quadratic levels: their
  // walls collide and render at twice these counts along each edge (8 x 10 x 1 draws a 16 x 20 wall; 12 x 16 x 1
  // about the paper's 20 x 26).
  std::vector<Level> levels = {{12, 16, 2}, {20, 26, 3}, {28, 36, 4}, {40, 52, 6}};
  std::vector<Level> quadratic_levels = {{8, 10, 1}, {12, 16, 1}, {16, 20, 2}, {20, 26, 2}};
  if (opt.quick) {
    levels = {{8, 10, 2}, {12, 16, 2}};
    quadratic_levels = {{8, 10, 1}};
  }
  if (opt.max_level + 1 < static_cast<int>(levels.size())) levels.resize(opt.max_level + 1);
  const std::vector<double> tolerances = opt.quick ? std::vector<double>{1e-2} : std::vector<double>{1e-2, 1e-3, 1e-4};

  if (!opt.capacity_only) {
    error_sweep(opt, levels, quadratic_levels, tolerances);
    if (!opt.load_out.empty()) load_sweep(opt);
  }
  if (!opt.capacity_out.empty()) capacity_sweep(opt);
  return 0;
}
