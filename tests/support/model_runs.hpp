#pragma once
// Test support: one scene run under each material model and solver type, and the checks that the models agree
// where they must (the organ-mesh tests: every model on every mesh source).
#include <cstdio>
#include <functional>
#include <string>

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "engine/scene.hpp"
#include "engine/simulation.hpp"

namespace lumen::test {

// Sets material.model and solver.type of a scene (dynamic: Rayleigh mass damping 2 per second).
inline void set_model(nlohmann::json& scene, const char* model, const char* solver) {
  scene["material"]["model"] = model;
  scene["solver"] = {{"type", solver}};
  if (std::string(solver) == "dynamic") scene["solver"]["rayleigh_mass"] = 2.0;
}

// The first probe's displacement at the scene's last frame, every frame stepped free of numerical failure.
inline Eigen::Vector3d last_probe_displacement(const engine::Scene& scene) {
  const auto m = engine::compile_model(scene);
  engine::Inputs inputs = engine::make_inputs(scene);
  engine::State state = engine::make_state(*m);
  engine::FrameRecord rec;
  for (int i = 0; i < scene.frames; ++i) {
    engine::step(*m, inputs, state, rec);
    EXPECT_FALSE(rec.numerical_failure) << scene.name << " frame " << i;
  }
  return rec.probe_displacement.at(0);
}

// A case's probe displacement under (material model, solver type, peak force in newtons, frames).
using ModelRun = std::function<Eigen::Vector3d(const char* model, const char* solver, double force, int frames)>;

// Every model on one case: the corotational quasi-static answer approaches the linear one to second order as the
// load shrinks (at `big` newtons under 10 % apart, at a tenth of it about a tenth of that), and the dynamic runs
// (320 frames, the load held) settle on their quasi-static answers (linear 1e-4, corotational 1e-3 relative).
// Prints the numbers under `what`; linear_big (optional): the linear quasi-static displacement at `big`.
inline void expect_every_model_agrees(const ModelRun& run, double big, const char* what,
                                      Eigen::Vector3d* linear_big_out = nullptr) {
  const double small = 0.1 * big;
  const Eigen::Vector3d linear_big = run("linear", "quasi_static", big, 8);
  const Eigen::Vector3d corot_big = run("corotational", "quasi_static", big, 8);
  const Eigen::Vector3d linear_small = run("linear", "quasi_static", small, 8);
  const Eigen::Vector3d corot_small = run("corotational", "quasi_static", small, 8);
  if (linear_big_out) *linear_big_out = linear_big;
  ASSERT_GT(linear_big.norm(), 1e-4);  // a real deflection (0.1 mm or more)
  const double diff_big = (corot_big - linear_big).norm() / linear_big.norm();
  const double diff_small = (corot_small - linear_small).norm() / linear_small.norm();
  EXPECT_LT(diff_big, 0.1);
  EXPECT_GT(diff_big, 0.0);
  EXPECT_NEAR(diff_small / diff_big, 0.1, 0.05) << diff_small << " vs " << diff_big;
  const Eigen::Vector3d linear_dynamic = run("linear", "dynamic", big, 320);
  EXPECT_LT((linear_dynamic - linear_big).norm(), 1e-4 * linear_big.norm()) << linear_dynamic.transpose();
  const Eigen::Vector3d corot_dynamic = run("corotational", "dynamic", big, 320);
  EXPECT_LT((corot_dynamic - corot_big).norm(), 1e-3 * corot_big.norm()) << corot_dynamic.transpose();
  std::printf("%s probe at %.0f mN: linear %.4f mm, corotational %.4f mm (%.2f %%; at a tenth of the load %.3f %%), "
              "dynamic settled to %.2g / %.2g of them\n",
              what, big * 1e3, linear_big.norm() * 1e3, corot_big.norm() * 1e3, 100.0 * diff_big, 100.0 * diff_small,
              (linear_dynamic - linear_big).norm() / linear_big.norm(),
              (corot_dynamic - corot_big).norm() / corot_big.norm());
}

}  // namespace lumen::test
