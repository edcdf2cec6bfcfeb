// Corotational quasi-static solve on the paper mesh (20 x 26 x 3: 2160 nodes, 9360 tets), E 5000 Pa, nu 0.45,
// both ends fixed, under a probe-like load ramp: the fig5-squeeze probe point (0, 0.013, 0.05) m on the outer
// wall pushes along -y, its force spread over the outer-wall nodes within 5 mm of the point, growing linearly
// from 0 to the peak over 80 frames (2 s at 40 fps). Each frame is one solve_corotational warm-started from the
// previous frame (PCG preconditioned with the rest-state CHOLMOD factorisation, no refactorisation).
//
// BM_CorotationalProbeRamp/<peak mN>/<rotated preconditioner>/<extrapolate>/<tolerance 10^-k>: default options
// except those; the reported time is the MEDIAN
// per-frame physics time over the ramp (manual time); counters: p99_ms, max_ms, outer and CG iterations per frame,
// refactorisations per ramp,
// max_rel_error = max over frames of |u - u_tight| / |u_tight| against a tightly converged solve (tolerance
// 1e-10), max_u_mm the largest displacement at the peak, inverted = inverted tets at the peak.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <vector>

#include "physics/corotational.hpp"
#include "physics/fem.hpp"
#include "physics/mesh.hpp"

namespace {

using namespace lumen;
using namespace lumen::physics;

constexpr int kFrames = 80;

// The paper model and the probe patch, built once.
struct CorotPaperModel {
  TetMesh mesh = make_hollow_cylinder(HollowCylinderSpec{});
  std::vector<int> fixed;
  std::unique_ptr<CorotationalModel> model;
  std::vector<int> patch;  // outer-wall nodes within 5 mm of the probe point
  std::map<int, std::vector<Eigen::VectorXd>> tight;  // per peak (mN): tightly converged u per frame

  CorotPaperModel() {
    fixed = mesh.node_set(kStartEnd);
    fixed.insert(fixed.end(), mesh.node_set(kStopEnd).begin(), mesh.node_set(kStopEnd).end());
    model = std::make_unique<CorotationalModel>(mesh, LinearMaterial{5000.0, 0.45}, fixed);
    const Eigen::RowVector3d probe(0.0, 0.013, 0.05);
    std::vector<char> on(mesh.n_nodes(), 0);
    for (int i = 0; i < mesh.surface(kOuterWall).size(); ++i) on[mesh.surface(kOuterWall).data()[i]] = 1;
    for (int v = 0; v < mesh.n_nodes(); ++v)
      if (on[v] && (mesh.rest.row(v) - probe).norm() <= 0.005 + 1e-9) patch.push_back(v);
  }
  // Loads of frame k (1..kFrames) of a ramp to peak newtons.
  Eigen::VectorXd load(double peak, int k) const {
    Eigen::VectorXd f = Eigen::VectorXd::Zero(model->n_dofs());
    for (int v : patch) f[3 * v + 1] = -peak * k / kFrames / patch.size();
    return f;
  }
  // Tightly converged solutions of the ramp (computed once per peak, untimed).
  const std::vector<Eigen::VectorXd>& tight_solutions(int peak_mN) {
    auto it = tight.find(peak_mN);
    if (it != tight.end()) return it->second;
    CorotationalOptions opt;
    opt.tolerance = 1e-10;
    opt.max_iterations = 500;
    opt.max_cg_iterations = 1000;
    opt.extrapolate = true;
    CorotationalState s;
    std::vector<Eigen::VectorXd> u;
    for (int k = 1; k <= kFrames; ++k) {
      solve_corotational(*model, load(1e-3 * peak_mN, k), s, opt);
      u.push_back(s.u);
    }
    return tight[peak_mN] = u;
  }
};

CorotPaperModel& corot_model() {
  static CorotPaperModel m;
  return m;
}

// The state at the end of the last ramp: the largest displacement (metres) and the inverted tets.
struct RampEnd {
  double max_u = 0.0;
  int inverted = 0;
};

// Runs one ramp from rest per benchmark iteration (every frame warm-started from the previous one; the iteration
// time is the ramp's median frame) and sets the counters: median_ms, p99_ms, max_ms, outer and CG iterations per
// frame, refactorisations per ramp, frames not converged, max_rel_error against the tight solutions.
RampEnd run_ramps(benchmark::State& state, CorotPaperModel& m, int peak_mN, const CorotationalOptions& opt) {
  const std::vector<Eigen::VectorXd>& tight = m.tight_solutions(peak_mN);
  std::vector<double> frame_ms;
  long outer = 0, cg = 0, frames = 0, not_converged = 0, refactorisations = 0;
  double max_error = 0.0;
  RampEnd end;
  for (auto _ : state) {
    CorotationalState s;
    std::vector<double> ramp_ms;
    for (int k = 1; k <= kFrames; ++k) {
      const Eigen::VectorXd f = m.load(1e-3 * peak_mN, k);
      const auto t0 = std::chrono::steady_clock::now();
      const CorotationalResult r = solve_corotational(*m.model, f, s, opt);
      ramp_ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
      outer += r.iterations, cg += r.cg_iterations, ++frames, refactorisations += r.refactorisations;
      not_converged += r.converged ? 0 : 1;
      max_error = std::max(max_error, (s.u - tight[k - 1]).norm() / tight[k - 1].norm());
      if (k == kFrames) end.max_u = s.u.cwiseAbs().maxCoeff(), end.inverted = r.n_inverted;
    }
    frame_ms.insert(frame_ms.end(), ramp_ms.begin(), ramp_ms.end());
    std::sort(ramp_ms.begin(), ramp_ms.end());
    state.SetIterationTime(1e-3 * ramp_ms[ramp_ms.size() / 2]);
  }
  std::sort(frame_ms.begin(), frame_ms.end());
  state.counters["median_ms"] = frame_ms[frame_ms.size() / 2];
  state.counters["p99_ms"] = frame_ms[static_cast<size_t>(0.99 * (frame_ms.size() - 1))];
  state.counters["max_ms"] = frame_ms.back();
  state.counters["outer_per_frame"] = static_cast<double>(outer) / frames;
  state.counters["cg_per_frame"] = static_cast<double>(cg) / frames;
  state.counters["refactor_per_ramp"] = static_cast<double>(refactorisations) / state.iterations();
  state.counters["not_converged"] = static_cast<double>(not_converged);
  state.counters["max_rel_error"] = max_error;
  return end;
}

void BM_CorotationalProbeRamp(benchmark::State& state) {
  CorotationalOptions opt;
  opt.rotate_preconditioner = state.range(1) != 0;
  opt.extrapolate = state.range(2) != 0;
  opt.tolerance = std::pow(10.0, -static_cast<double>(state.range(3)));
  const RampEnd end = run_ramps(state, corot_model(), static_cast<int>(state.range(0)), opt);
  state.counters["max_u_mm"] = 1e3 * end.max_u;
  state.counters["inverted"] = end.inverted;
}
BENCHMARK(BM_CorotationalProbeRamp)
    ->ArgNames({"peak_mN", "rotated", "extrapolate", "tol_exp"})
    ->Args({10, 0, 1, 3})
    ->Args({10, 0, 0, 3})
    ->Args({10, 1, 1, 3})
    ->Args({10, 0, 1, 4})
    ->Args({30, 0, 1, 3})
    ->Args({30, 1, 1, 3})
    ->UseManualTime()
    ->Iterations(3)
    ->Unit(benchmark::kMillisecond);

// The engine's solve options (extrapolated start, lagged factorisation refreshed after a slow solve, Anderson
// depth 5) on the same ramp, factorising inside the solve (deterministic), by method and preconditioner:
// BM_CorotationalRampLagged/<peak mN>/<chord>/<tangent: 0 warped, 2 exact>/<tolerance 10^(-k/10)>: counters as
// above (run_ramps).
void BM_CorotationalRampLagged(benchmark::State& state) {
  CorotationalOptions opt;
  opt.extrapolate = true;
  opt.refactor_cg_iterations = 5;
  opt.anderson_depth = 5;
  opt.method = state.range(1) != 0 ? CorotationalMethod::chord : CorotationalMethod::pcg;
  opt.tangent = state.range(2) == 2 ? CorotationalTangent::exact : CorotationalTangent::warped;
  opt.tolerance = std::pow(10.0, -0.1 * static_cast<double>(state.range(3)));
  run_ramps(state, corot_model(), static_cast<int>(state.range(0)), opt);
}
BENCHMARK(BM_CorotationalRampLagged)
    ->ArgNames({"peak_mN", "chord", "tangent", "tol_exp10"})
    ->ArgsProduct({{80}, {0, 1}, {0}, {30, 25, 20, 15}})
    ->Args({80, 0, 2, 30})
    ->Args({80, 0, 2, 20})
    ->UseManualTime()
    ->Iterations(1)
    ->Unit(benchmark::kMillisecond);

// The kernels of one outer iteration at a deformed state (frame 40 of the 30 mN ramp).
const Eigen::VectorXd& deformed_state() {
  static const Eigen::VectorXd u = corot_model().tight_solutions(30)[kFrames / 2 - 1];
  return u;
}

void BM_CorotationalRotations(benchmark::State& state) {
  const CorotationalElements& el = corot_model().model->elements();
  const Eigen::VectorXd& u = deformed_state();
  std::vector<Eigen::Matrix3d> R;
  for (auto _ : state) benchmark::DoNotOptimize(el.rotations(u, R));
  state.SetItemsProcessed(state.iterations() * el.n_tets());
}
BENCHMARK(BM_CorotationalRotations)->Unit(benchmark::kMicrosecond);

void BM_CorotationalElasticForces(benchmark::State& state) {
  const CorotationalElements& el = corot_model().model->elements();
  const Eigen::VectorXd& u = deformed_state();
  std::vector<Eigen::Matrix3d> R;
  el.rotations(u, R);
  Eigen::VectorXd f;
  for (auto _ : state) {
    el.elastic_forces(u, R, f);
    benchmark::DoNotOptimize(f.data());
  }
}
BENCHMARK(BM_CorotationalElasticForces)->Unit(benchmark::kMicrosecond);

// The evaluation at u in one pass (what evaluate_at_u runs), against BM_CorotationalRotations plus
// BM_CorotationalElasticForces.
void BM_CorotationalRotationsAndForces(benchmark::State& state) {
  const CorotationalElements& el = corot_model().model->elements();
  const Eigen::VectorXd& u = deformed_state();
  std::vector<Eigen::Matrix3d> R;
  Eigen::VectorXd f;
  double energy = 0.0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(el.rotations_and_forces(u, R, f, &energy));
    benchmark::DoNotOptimize(f.data());
  }
}
BENCHMARK(BM_CorotationalRotationsAndForces)->Unit(benchmark::kMicrosecond);

void BM_CorotationalWarpedProduct(benchmark::State& state) {
  const CorotationalElements& el = corot_model().model->elements();
  const Eigen::VectorXd& u = deformed_state();
  std::vector<Eigen::Matrix3d> R;
  el.rotations(u, R);
  Eigen::VectorXd y;
  for (auto _ : state) {
    el.warped_product(R, u, y);
    benchmark::DoNotOptimize(y.data());
  }
}
BENCHMARK(BM_CorotationalWarpedProduct)->Unit(benchmark::kMicrosecond);

// The lagged preconditioner's refresh at the deformed state: assembling K_w (triplets), then factorising it
// afresh (ordering and supernodes: arg 0) or on the rest factorisation's symbolic analysis (arg 1,
// StaticSolver::refactorised, what the solve does).
void BM_CorotationalWarpedStiffness(benchmark::State& state) {
  const CorotationalElements& el = corot_model().model->elements();
  std::vector<Eigen::Matrix3d> R;
  el.rotations(deformed_state(), R);
  for (auto _ : state) benchmark::DoNotOptimize(el.warped_stiffness(R).nonZeros());
}
BENCHMARK(BM_CorotationalWarpedStiffness)->Unit(benchmark::kMillisecond);

void BM_CorotationalRefactorise(benchmark::State& state) {
  const CorotPaperModel& m = corot_model();
  const CorotationalElements& el = m.model->elements();
  std::vector<Eigen::Matrix3d> R;
  el.rotations(deformed_state(), R);
  const Eigen::SparseMatrix<double> K = el.warped_stiffness(R);
  for (auto _ : state) {
    if (state.range(0) == 0) {
      StaticSolver s(K, m.fixed);
      benchmark::DoNotOptimize(s.n_free_dofs());
    } else {
      StaticSolver s = m.model->solver().refactorised(K);
      benchmark::DoNotOptimize(s.n_free_dofs());
    }
  }
}
BENCHMARK(BM_CorotationalRefactorise)->ArgName("on_rest_analysis")->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

}  // namespace
