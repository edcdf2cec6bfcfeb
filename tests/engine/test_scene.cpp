// Scene loader: every refused input names the file, the key path and the value.
#include <gtest/gtest.h>

#include <fstream>

#include <nlohmann/json.hpp>

#include "engine/scene.hpp"
#include "support/scene_files.hpp"

using lumen::engine::InputError;
using lumen::engine::parse_scene;
using lumen::engine::ResponseKind;
using lumen::engine::LcpSolver;
using lumen::engine::SolverType;
using lumen::engine::Tangent;
using lumen::engine::TwistEnd;
namespace render = lumen::render;
using nlohmann::json;

namespace {

json good_scene() {
  return json::parse(R"({
    "name": "t",
    "mesh": {"type": "hollow_cylinder", "inner_radius": 0.01, "outer_radius": 0.013, "length": 0.1,
             "segments_around": 20, "segments_along": 26, "layers": 3},
    "material": {"model": "linear", "young_modulus": 5000.0, "poisson_ratio": 0.45, "density": 1050.0},
    "fixed": ["ends"],
    "probes": [{"point": [0.0, 0.013, 0.05], "track": [{"t": 0.0, "force": [0, 0, 0]}, {"t": 2.0, "force": [0, -0.4, 0]}]}],
    "frames": 120, "fps": 40,
    "render": {"width": 640, "height": 480, "camera": "diagonal", "video": true}
  })");
}

// Message of the InputError thrown for `scene`, or "" when accepted.
using lumen::test::scene_parse_error;

}  // namespace

TEST(Scene, AcceptsTheIssueExampleWithItsValues) {
  auto s = parse_scene(good_scene().dump(), "dir/s.json");
  EXPECT_EQ(s.name, "t");
  EXPECT_EQ(s.mesh.segments_around, 20);
  EXPECT_DOUBLE_EQ(s.material.poisson_ratio, 0.45);
  ASSERT_EQ(s.probes.size(), 1u);
  ASSERT_EQ(s.probes[0].track.size(), 2u);
  EXPECT_DOUBLE_EQ(s.probes[0].track[1].value.y(), -0.4);
  EXPECT_EQ(s.probes[0].drive, lumen::engine::ProbeDrive::Force);
  EXPECT_EQ(s.render.camera, render::CameraPreset::Diagonal);
  EXPECT_TRUE(s.render.video);
  EXPECT_FALSE(s.collision.self);
}

TEST(Scene, MalformedJsonNamesTheFile) {
  try {
    parse_scene("{\"name\": ", "dir/s.json");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("dir/s.json: malformed JSON"), std::string::npos) << e.what();
  }
}

TEST(Scene, UnknownKeyIsNamedWithItsPath) {
  json s = good_scene();
  s["material"]["stiffness"] = 3;
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: material.stiffness: unknown key");
  s = good_scene();
  s["colour"] = "red";
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: colour: unknown key");
}

TEST(Scene, MissingKeyIsNamed) {
  json s = good_scene();
  s["mesh"].erase("layers");
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: mesh.layers: missing key");
  s = good_scene();
  s.erase("fps");
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: fps: missing key");
}

TEST(Scene, WrongTypesNameKeyAndValue) {
  json s = good_scene();
  s["mesh"]["inner_radius"] = "0.01";
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: mesh.inner_radius: must be a number (value \"0.01\")");
  s = good_scene();
  s["mesh"]["layers"] = 2.5;
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: mesh.layers: must be an integer (value 2.5)");
  s = good_scene();
  s["render"]["video"] = 1;
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: render.video: must be true or false (value 1)");
  s = good_scene();
  s["probes"][0]["point"] = json::array({0, 1});
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: probes[0].point: must be an array of 3 numbers (value [0,1])");
}

TEST(Scene, OutOfRangeValues) {
  json s = good_scene();
  s["mesh"]["inner_radius"] = 0.0;
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: mesh.inner_radius: must be > 0 (value 0.0)");
  s = good_scene();
  s["mesh"]["inner_radius"] = -0.01;
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: mesh.inner_radius: must be > 0 (value -0.01)");
  s = good_scene();
  s["mesh"]["inner_radius"] = 0.02;
  EXPECT_NE(scene_parse_error(s).find("dir/s.json: mesh.inner_radius: must be < mesh.outer_radius"), std::string::npos);
  EXPECT_NE(scene_parse_error(s).find("(value 0.02)"), std::string::npos);
  s = good_scene();
  s["material"]["poisson_ratio"] = 0.5;
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: material.poisson_ratio: out of range (-1, 0.5) (value 0.5)");
  s = good_scene();
  s["material"]["poisson_ratio"] = -1.0;
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: material.poisson_ratio: out of range (-1, 0.5) (value -1.0)");
  s = good_scene();
  s["fps"] = 0;
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: fps: out of range (0, 10000] (value 0)");
  s = good_scene();
  s["render"]["width"] = 641;
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: render.width: must be even (video encoding) (value 641)");
  s = good_scene();
  s["render"]["camera"] = "top";
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: render.camera: must be one of side, diagonal, endoscope (value \"top\")");
  s = good_scene();
  s["fixed"] = json::array({"both"});
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: fixed[0]: must be one of ends, start, stop (value \"both\")");
}

TEST(Scene, NonFiniteNumbersAreRefused) {
  // JSON has no NaN literal; a huge exponent overflows when read and is refused with the file and the value.
  std::string text = good_scene().dump();
  const std::string key = "\"young_modulus\":5000.0";
  ASSERT_NE(text.find(key), std::string::npos);
  text.replace(text.find(key), key.size(), "\"young_modulus\":1e999");
  try {
    parse_scene(text, "dir/s.json");
    FAIL();
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_EQ(msg.rfind("dir/s.json: malformed JSON: ", 0), 0u) << msg;
    EXPECT_NE(msg.find("1e999"), std::string::npos) << msg;
  }
}

TEST(Scene, TrackMustBeNonEmptyAndIncreasing) {
  json s = good_scene();
  s["probes"][0]["track"] = json::array();
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: probes[0].track: must not be empty (value [])");
  s = good_scene();
  s["probes"][0]["track"][1]["t"] = 0.0;
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: probes[0].track[1].t: track times must be strictly increasing (value 0.0)");
  s = good_scene();
  s["probes"][0]["track"][0]["force"][2] = "x";
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: probes[0].track[0].force[2]: must be a number (value \"x\")");
}

TEST(Scene, DisplacementDrivenProbe) {
  json s = good_scene();
  s["probes"][0]["track"] = json::parse(R"([{"t": 0, "displacement": [0, 0, 0]}, {"t": 1, "displacement": [0, -0.004, 0]}])");
  auto scene = parse_scene(s.dump(), "dir/s.json");
  EXPECT_EQ(scene.probes[0].drive, lumen::engine::ProbeDrive::Displacement);
  EXPECT_DOUBLE_EQ(scene.probes[0].track[1].value.y(), -0.004);
  // Keys must not mix force and displacement.
  s["probes"][0]["track"][1] = json::parse(R"({"t": 1, "force": [0, -0.1, 0]})");
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: probes[0].track[1].force: unknown key");
}

TEST(Scene, ReplayPathIsResolvedBesideTheScene) {
  json s = good_scene();
  s["probes"][0].erase("track");
  s["probes"][0]["replay"] = "session.csv";
  auto scene = parse_scene(s.dump(), "dir/s.json");
  EXPECT_EQ(scene.probes[0].replay, "dir/session.csv");
  s["probes"][0]["track"] = good_scene()["probes"][0]["track"];
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: probes[0]: needs exactly one of \"track\" or \"replay\"");
}

TEST(Scene, CollisionKeys) {
  json s = good_scene();
  s["collision"] = {{"self", true}, {"kdop", 18}, {"response", "paper"}, {"gap", 1e-4}};
  auto scene = parse_scene(s.dump(), "dir/s.json");
  EXPECT_TRUE(scene.collision.self);
  EXPECT_EQ(scene.collision.kdop, 18);
  EXPECT_EQ(scene.collision.response, ResponseKind::kPaper);
  s["collision"]["kdop"] = 10;
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: collision.kdop: must be one of 6, 14, 18, 26 (value 10)");
}

TEST(Scene, LcpSolverKeys) {
  json s = good_scene();
  s["collision"] = {{"self", true}, {"lcp", "nncg"}, {"lcp_sweeps", 50}};
  auto scene = parse_scene(s.dump(), "dir/s.json");
  EXPECT_EQ(scene.collision.lcp, LcpSolver::kNncg);
  EXPECT_EQ(scene.collision.lcp_sweeps, 50);
  EXPECT_EQ(parse_scene(good_scene().dump(), "dir/s.json").collision.lcp, LcpSolver::kActiveSet);
  s["collision"]["lcp_sweeps"] = 1;
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: collision.lcp_sweeps: out of range [2, 100000] (value 1)");
  s["collision"]["lcp_sweeps"] = 50;
  s["collision"]["lcp"] = "pgs";
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: collision.lcp: must be one of active_set, nncg (value \"pgs\")");
  s["collision"]["lcp"] = "nncg";
  s["collision"]["response"] = "paper";
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: collision.lcp: \"nncg\" needs collision.response \"constraint\" (got \"paper\") (value \"nncg\")");
}

TEST(Scene, CouplingKey) {
  json s = good_scene();
  s["material"]["model"] = "corotational";
  s["collision"] = {{"self", true}, {"coupling", "carried"}};
  EXPECT_EQ(parse_scene(s.dump(), "dir/s.json").collision.coupling, lumen::engine::ContactCoupling::kCarried);
  EXPECT_EQ(parse_scene(good_scene().dump(), "dir/s.json").collision.coupling, lumen::engine::ContactCoupling::kCorrect);
  s["collision"]["coupling"] = "warped";
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: collision.coupling: must be one of correct, carried, solved (value \"warped\")");
  s["collision"]["coupling"] = "carried";
  s["material"]["model"] = "linear";
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: collision.coupling: \"carried\" needs material.model \"corotational\" and "
                         "solver.type \"quasi_static\" (got \"linear\", \"quasi_static\") (value \"carried\")");
  s["material"]["model"] = "corotational";
  s["collision"]["response"] = "paper";
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: collision.coupling: \"carried\" needs collision.response \"constraint\" "
                         "(got \"paper\") (value \"carried\")");
  // "solved": the same needs, its step bound and its Hessian.
  s["collision"] = {{"self", true}, {"coupling", "solved"}, {"equilibrium_steps", 7}, {"equilibrium_hessian", "warped_rest"}};
  const lumen::engine::Scene solved = parse_scene(s.dump(), "dir/s.json");
  EXPECT_EQ(solved.collision.coupling, lumen::engine::ContactCoupling::kSolved);
  EXPECT_EQ(solved.collision.equilibrium_steps, 7);
  EXPECT_EQ(solved.collision.equilibrium_hessian, lumen::engine::EquilibriumHessian::kWarpedRest);
  EXPECT_EQ(parse_scene(good_scene().dump(), "dir/s.json").collision.equilibrium_hessian,
            lumen::engine::EquilibriumHessian::kLagged);
  s["collision"]["equilibrium_steps"] = 0;
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: collision.equilibrium_steps: out of range [1, 1000] (value 0)");
  s["collision"]["equilibrium_steps"] = 7;
  s["collision"]["equilibrium_hessian"] = "exact";
  EXPECT_EQ(scene_parse_error(s),
            "dir/s.json: collision.equilibrium_hessian: must be one of lagged, warped_rest (value \"exact\")");
  s["collision"]["equilibrium_hessian"] = "lagged";
  // The prediction's bound after a contact frame: 0 or >= 2, on the lagged Hessian of "solved", with PCG steps.
  EXPECT_EQ(parse_scene(s.dump(), "dir/s.json").collision.prediction_back_substitutions, 0);
  s["collision"]["prediction_back_substitutions"] = 3;
  EXPECT_EQ(parse_scene(s.dump(), "dir/s.json").collision.prediction_back_substitutions, 3);
  s["collision"]["prediction_back_substitutions"] = 1;
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: collision.prediction_back_substitutions: must be 0 "
                                  "(solver.max_back_substitutions) or >= 2 (a PCG step takes two) (value 1)");
  s["collision"]["prediction_back_substitutions"] = 2;
  s["collision"]["equilibrium_hessian"] = "warped_rest";
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: collision.prediction_back_substitutions: needs collision.coupling "
                                  "\"solved\" with equilibrium_hessian \"lagged\" (got \"solved\", \"warped_rest\") (value 2)");
  s["collision"]["equilibrium_hessian"] = "lagged";
  s["solver"] = {{"method", "chord"}};
  EXPECT_EQ(scene_parse_error(s),
            "dir/s.json: collision.prediction_back_substitutions: needs solver.method \"pcg\" (got \"chord\") (value 2)");
  s.erase("solver");
  s["collision"].erase("prediction_back_substitutions");
  s["material"]["model"] = "linear";
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: collision.coupling: \"solved\" needs material.model \"corotational\" and "
                         "solver.type \"quasi_static\" (got \"linear\", \"quasi_static\") (value \"solved\")");
}

TEST(Scene, SolverMethodKey) {
  json s = good_scene();
  s["material"]["model"] = "corotational";
  EXPECT_EQ(parse_scene(s.dump(), "dir/s.json").solver.method, lumen::engine::SolveMethod::kPcg);
  s["solver"] = {{"method", "chord"}};
  EXPECT_EQ(parse_scene(s.dump(), "dir/s.json").solver.method, lumen::engine::SolveMethod::kChord);
  s["solver"]["method"] = "newton";
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: solver.method: must be one of pcg, chord (value \"newton\")");
  s["solver"] = {{"method", "chord"}, {"tangent", "exact"}};
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: solver.method: \"chord\" needs solver.tangent \"warped\" (got \"exact\") "
                         "(value \"chord\")");
  s["solver"] = {{"method", "chord"}};
  s["material"]["model"] = "linear";
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: solver.method: needs material.model \"corotational\" and solver.type "
                         "\"quasi_static\" (got \"linear\", \"quasi_static\") (value \"chord\")");
}

TEST(Scene, UnreadableFile) {
  try {
    lumen::engine::load_scene("/nonexistent/scene.json");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "/nonexistent/scene.json: no such scene file");
  }
}

TEST(Scene, SolverKeysWithDefaultsAndValues) {
  auto d = parse_scene(good_scene().dump(), "dir/s.json");
  EXPECT_EQ(d.solver.type, SolverType::kQuasiStatic);
  EXPECT_DOUBLE_EQ(d.solver.tolerance, 1e-3);
  EXPECT_EQ(d.solver.max_iterations, 20);
  EXPECT_EQ(d.solver.rayleigh_mass, 0.0);
  EXPECT_EQ(d.solver.rayleigh_stiffness, 0.0);
  EXPECT_TRUE(d.solver.background_factorisation);
  EXPECT_EQ(d.solver.tangent, Tangent::kWarped);
  json s = good_scene();
  s["solver"] = json::parse(R"({"type": "dynamic", "tolerance": 1e-6, "max_iterations": 7, "rayleigh_mass": 2.5,
                                "rayleigh_stiffness": 0.01, "background_factorisation": false})");
  auto scene = parse_scene(s.dump(), "dir/s.json");
  EXPECT_EQ(scene.solver.type, SolverType::kDynamic);
  EXPECT_DOUBLE_EQ(scene.solver.tolerance, 1e-6);
  EXPECT_EQ(scene.solver.max_iterations, 7);
  EXPECT_DOUBLE_EQ(scene.solver.rayleigh_mass, 2.5);
  EXPECT_DOUBLE_EQ(scene.solver.rayleigh_stiffness, 0.01);
  EXPECT_FALSE(scene.solver.background_factorisation);
  json c = good_scene();
  c["material"]["model"] = "corotational";
  c["solver"] = {{"tangent", "exact"}};
  EXPECT_EQ(parse_scene(c.dump(), "dir/s.json").solver.tangent, Tangent::kExact);
  EXPECT_EQ(d.solver.max_back_substitutions, 0);
  c["solver"] = {{"max_back_substitutions", 6}};
  EXPECT_EQ(parse_scene(c.dump(), "dir/s.json").solver.max_back_substitutions, 6);
  c["solver"]["method"] = "chord";
  EXPECT_EQ(scene_parse_error(c), "dir/s.json: solver.max_back_substitutions: needs solver.method \"pcg\" (got "
                                  "\"chord\") (value 6)");
}

TEST(Scene, SolverKeysAreValidated) {
  json s = good_scene();
  s["solver"] = {{"type", "explicit"}};
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: solver.type: must be one of quasi_static, dynamic (value \"explicit\")");
  s["solver"] = {{"type", "dynamic"}, {"damping", 1.0}};
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: solver.damping: unknown key");
  s["solver"] = {{"tolerance", 0.0}};
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: solver.tolerance: out of range (0, 1) (value 0.0)");
  s["solver"] = {{"tolerance", 1.0}};
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: solver.tolerance: out of range (0, 1) (value 1.0)");
  s["solver"] = {{"background_factorisation", 1}};
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: solver.background_factorisation: must be true or false (value 1)");
  s["solver"] = {{"tolerance", "tight"}};
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: solver.tolerance: must be a number (value \"tight\")");
  s["solver"] = {{"max_iterations", 0}};
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: solver.max_iterations: out of range [1, 10000] (value 0)");
  s["solver"] = {{"anderson_depth", 21}};
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: solver.anderson_depth: out of range [0, 20] (value 21)");
  s["solver"] = {{"max_back_substitutions", 1}};
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: solver.max_back_substitutions: must be 0 (no bound) or >= 2 (a PCG "
                                  "step takes two) (value 1)");
  s["solver"] = {{"max_back_substitutions", -3}};
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: solver.max_back_substitutions: out of range [0, 1000000] (value -3)");
  s["solver"] = {{"max_back_substitutions", 8}};  // (good_scene is linear)
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: solver.max_back_substitutions: needs material.model \"corotational\" "
                                  "and solver.type \"quasi_static\" (got \"linear\", \"quasi_static\") (value 8)");
  s["solver"] = {{"tangent", "newton"}};
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: solver.tangent: must be one of warped, projected, exact (value \"newton\")");
  s["solver"] = {{"tangent", "exact"}};  // (good_scene is linear)
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: solver.tangent: needs material.model \"corotational\" and solver.type "
                         "\"quasi_static\" (got \"linear\", \"quasi_static\") (value \"exact\")");
  s["solver"] = {{"max_iterations", 2.5}};
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: solver.max_iterations: must be an integer (value 2.5)");
  s["solver"] = {{"type", "dynamic"}, {"rayleigh_mass", -0.1}};
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: solver.rayleigh_mass: must be >= 0 (value -0.1)");
  s["solver"] = {{"type", "dynamic"}, {"rayleigh_stiffness", -1e-3}};
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: solver.rayleigh_stiffness: must be >= 0 (value -0.001)");
  s["solver"] = {{"type", "dynamic"}, {"rayleigh_stiffness", nullptr}};
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: solver.rayleigh_stiffness: must be a number (value null)");
  // Damping without a dynamic solve is a mistake, not a no-op.
  s["solver"] = {{"rayleigh_mass", 1.0}};
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: solver.rayleigh_mass: needs solver.type \"dynamic\" (value 1.0)");
  s["solver"] = "dynamic";
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: solver: must be an object (value \"dynamic\")");
}

TEST(Scene, TwistKeysWithTheirValues) {
  EXPECT_FALSE(parse_scene(good_scene().dump(), "dir/s.json").twist.enabled());
  json s = good_scene();
  s["twist"] = json::parse(R"({"end": "stop", "track": [{"t": 0.0, "degrees": 0.0}, {"t": 3.0, "degrees": 180.0}]})");
  auto scene = parse_scene(s.dump(), "dir/s.json");
  EXPECT_TRUE(scene.twist.enabled());
  EXPECT_EQ(scene.twist.end, TwistEnd::kStop);
  ASSERT_EQ(scene.twist.track.size(), 2u);
  EXPECT_DOUBLE_EQ(scene.twist.track[1].t, 3.0);
  EXPECT_DOUBLE_EQ(scene.twist.track[1].degrees, 180.0);
  s["twist"]["end"] = "start";
  EXPECT_EQ(parse_scene(s.dump(), "dir/s.json").twist.end, TwistEnd::kStart);
}

TEST(Scene, TwistKeysAreValidated) {
  const json good = json::parse(R"({"end": "stop", "track": [{"t": 0.0, "degrees": 0.0}, {"t": 3.0, "degrees": 180.0}]})");
  json s = good_scene();
  s["twist"] = good;
  s["twist"]["end"] = "middle";
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: twist.end: must be one of start, stop (value \"middle\")");
  s["twist"] = good;
  s["twist"].erase("end");
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: twist.end: missing key");
  s["twist"] = good;
  s["twist"].erase("track");
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: twist.track: missing key");
  s["twist"] = good;
  s["twist"]["axis"] = json::array({0, 0, 1});
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: twist.axis: unknown key");
  s["twist"] = good;
  s["twist"]["track"] = json::array();
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: twist.track: must not be empty (value [])");
  s["twist"]["track"] = 90;
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: twist.track: must be an array of {\"t\", \"degrees\"} keys (value 90)");
  s["twist"] = good;
  s["twist"]["track"][1]["t"] = 0.0;
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: twist.track[1].t: track times must be strictly increasing (value 0.0)");
  s["twist"] = good;
  s["twist"]["track"][0]["t"] = -0.5;
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: twist.track[0].t: must be >= 0 (value -0.5)");
  s["twist"] = good;
  s["twist"]["track"][1]["degrees"] = 1000.0;
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: twist.track[1].degrees: out of range [-720, 720] (value 1000.0)");
  s["twist"] = good;
  s["twist"]["track"][1]["degrees"] = "half";
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: twist.track[1].degrees: must be a number (value \"half\")");
  s["twist"] = good;
  s["twist"]["track"][1].erase("degrees");
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: twist.track[1].degrees: missing key");
  s["twist"] = good;
  s["twist"]["track"][1]["radians"] = 3.14;
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: twist.track[1].radians: unknown key");
}

// mesh.grading: angles in degrees become radians, arc lengths stay metres; bad values are named by key path.
TEST(Scene, MeshGradingIsReadAndItsErrorsNamed) {
  json s = good_scene();
  s["mesh"]["grading"] = json::parse(R"({"around": {"at_deg": [90, 270], "ratio": 6}, "along": {"at": [0.05], "ratio": 12}})");
  const lumen::engine::Scene scene = parse_scene(s.dump(), "dir/s.json");
  ASSERT_EQ(scene.mesh.grading_around.focus.size(), 2u);
  EXPECT_NEAR(scene.mesh.grading_around.focus[1], 1.5 * EIGEN_PI, 1e-15);
  EXPECT_EQ(scene.mesh.grading_around.ratio, 6.0);
  ASSERT_EQ(scene.mesh.grading_along.focus.size(), 1u);
  EXPECT_EQ(scene.mesh.grading_along.focus[0], 0.05);
  EXPECT_EQ(scene.mesh.grading_along.ratio, 12.0);
  s["mesh"]["grading"]["around"]["ratio"] = 0.5;
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: mesh.grading.around.ratio: out of range [1, 100] (value 0.5)");
  s["mesh"]["grading"]["around"]["ratio"] = 6;
  s["mesh"]["grading"]["along"]["at"] = json::parse("[0.2]");
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: mesh.grading.along.at[0]: out of range [0, 0.1] (value 0.2)");
  s["mesh"]["grading"]["along"]["at"] = json::parse("[]");
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: mesh.grading.along.at: must be a non-empty array of numbers (value [])");
  s["mesh"]["grading"]["along"].erase("at");
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: mesh.grading.along.at: missing key");
  s["mesh"]["grading"]["sideways"] = json::object();
  EXPECT_EQ(scene_parse_error(s), "dir/s.json: mesh.grading.sideways: unknown key");
}
