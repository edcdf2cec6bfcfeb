// Self-collision response on the full-closure scene (two opposite probes squeeze the paper tube shut, about
// 590 contacts at the end): whole sessions (per-frame response and collision + response percentiles as
// counters), and the pieces of one late frame frozen after 100 frames: coupling matrix, Lemke against the
// active-set solver (cold and warm), whole-mesh correction by precomputed columns against a back-substitution,
// and the paper's hold (equality) solve.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "engine/report.hpp"
#include "engine/response.hpp"
#include "engine/scene.hpp"
#include "engine/session.hpp"
#include "engine/simulation.hpp"

namespace {

using namespace lumen;
using namespace lumen::engine;

const std::string kFullClosure = std::string(LUMEN_SOURCE_DIR) + "/scenes/full-closure.json";

// One late frame of the full-closure scene: the state after `frames` frames and the next frame's free motion,
// its contacts (last frame's pushing ones plus the new ones) as rows, and the warm-start guess.
struct FrozenFrame {
  std::unique_ptr<Model> model;
  Inputs inputs;
  State state;
  Eigen::VectorXd u_free;                   // 3n, metres
  std::vector<physics::ContactRow> rows;    // one per active contact
  std::vector<int> warm;                    // rows of last frame's pushing contacts
  std::vector<physics::ContactRow> held;    // the paper's hold of the same contacts: 3 unit rows per node

  explicit FrozenFrame(int frames) {
    const Scene scene = load_scene(kFullClosure);
    model = compile_model(scene);
    inputs = make_inputs(scene);
    state = make_state(*model);
    for (int f = 0; f < frames; ++f) {
      FrameRecord rec;
      step(*model, inputs, state, rec);
    }
    // The next frame's free motion (fixed probe points: the precomputed unit responses).
    const int n = model->mesh.n_nodes();
    const double t1 = (state.frame + 1) / model->fps;
    Points forces(inputs.sources.size(), 3);
    for (size_t i = 0; i < inputs.sources.size(); ++i) forces.row(i) = inputs.sources[i]->sample(t1).force.transpose();
    dynamic_cast<const physics::LinearQuasiStatic&>(*model->integrator).load_response().displacement(forces, u_free);
    const Points x1 = model->mesh.rest + Eigen::Map<const Points>(u_free.data(), n, 3);
    std::vector<collision::Contact> found;
    collision::detect_self(*model->collision_surface, *state.detector, state.x, x1, model->collision.gap, found,
                           nullptr);
    std::map<FeatureKey, collision::Contact> active;
    std::set<FeatureKey> pushing;
    for (const auto& c : state.active) active.emplace(key_of(c), c), pushing.insert(key_of(c));
    for (const auto& c : found) active[key_of(c)] = c;
    std::set<int> nodes;
    for (const auto& [key, c] : active) {
      if (pushing.count(key)) warm.push_back(static_cast<int>(rows.size()));
      rows.push_back(contact_row(c, model->mesh.rest, state.x, x1, model->collision.gap));
      for (int k = 0; k < 4; ++k) nodes.insert(c.v[k]);
    }
    for (int v : nodes)
      for (int axis = 0; axis < 3; ++axis) {
        physics::ContactRow r;
        r.node[0] = v;
        r.weight[0] = 1.0;
        r.n = Eigen::Vector3d::Unit(axis);
        r.g = state.x(v, axis) - model->mesh.rest(v, axis);
        held.push_back(r);
      }
  }
};

FrozenFrame& frozen() {
  static FrozenFrame f(100);
  return f;
}

void frame_counters(benchmark::State& state, const FrozenFrame& f) {
  state.counters["rows"] = static_cast<double>(f.rows.size());
  state.counters["warm"] = static_cast<double>(f.warm.size());
}

// Whole sessions without rendering; the per-frame percentiles are the counters (ms).
void BM_ResponseFullClosureSession(benchmark::State& state) {
  const Scene scene = load_scene(kFullClosure);
  auto model = compile_model(scene);
  SessionOptions opt;
  opt.render = false;
  std::vector<double> resp, both;
  long fallbacks = 0, iterations = 0;
  for (auto _ : state) {
    const SessionResult r = run_session(*model, make_inputs(scene), opt);
    for (const FrameRecord& f : r.frames) {
      resp.push_back(f.ms[kResponse]);
      both.push_back(f.ms[kCollision] + f.ms[kResponse]);
      fallbacks += f.fallback;
      iterations += f.response_iterations;
    }
  }
  const StageSummary sr = summarize(resp), sb = summarize(both);
  state.counters["response_median_ms"] = sr.median_ms;
  state.counters["response_p99_ms"] = sr.p99_ms;
  state.counters["response_max_ms"] = sr.max_ms;
  state.counters["coll+resp_median_ms"] = sb.median_ms;
  state.counters["coll+resp_p99_ms"] = sb.p99_ms;
  state.counters["fallback_frames"] = benchmark::Counter(static_cast<double>(fallbacks), benchmark::Counter::kAvgIterations);
  state.counters["response_iterations"] = benchmark::Counter(static_cast<double>(iterations), benchmark::Counter::kAvgIterations);
}
BENCHMARK(BM_ResponseFullClosureSession)->Unit(benchmark::kMillisecond)->Iterations(1)->Repetitions(3);

void BM_ResponseCouplingMatrixDense(benchmark::State& state) {
  FrozenFrame& f = frozen();
  for (auto _ : state) benchmark::DoNotOptimize(physics::coupling_matrix(*f.state.compliance, f.rows));
  frame_counters(state, f);
}
BENCHMARK(BM_ResponseCouplingMatrixDense)->Unit(benchmark::kMillisecond);

// The dense path: all of A, then Lemke's pivoting, then the correction.
void BM_ResponseLemke(benchmark::State& state) {
  FrozenFrame& f = frozen();
  physics::ContactResult r;
  for (auto _ : state) r = physics::solve_lcp(*f.state.compliance, f.rows, f.u_free);
  frame_counters(state, f);
  state.counters["pivots"] = r.iterations;
}
BENCHMARK(BM_ResponseLemke)->Unit(benchmark::kMillisecond);

// The active-set path on columns computed on demand; arg 0: cold start, 1: warm start from last frame's rows.
void BM_ResponseActiveSet(benchmark::State& state) {
  FrozenFrame& f = frozen();
  const std::vector<int> warm = state.range(0) ? f.warm : std::vector<int>{};
  physics::ContactResult r;
  for (auto _ : state) r = physics::solve_contacts(*f.state.compliance, f.rows, f.u_free, warm);
  frame_counters(state, f);
  state.counters["rounds"] = r.iterations;
  state.counters["pushing"] = static_cast<double>((r.lambda.array() > 0.0).count());
  state.counters["used_lemke"] = r.used_lemke;
}
BENCHMARK(BM_ResponseActiveSet)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// Whole-mesh correction for the frame's contact forces; arg 0: precomputed columns, 1: one back-substitution.
void BM_ResponseWholeMeshCorrection(benchmark::State& state) {
  FrozenFrame& f = frozen();
  const physics::ContactResult r = physics::solve_contacts(*f.state.compliance, f.rows, f.u_free, f.warm);
  Eigen::VectorXd du;
  for (auto _ : state) {
    if (state.range(0) == 0)
      f.state.compliance->displacement(r.force, du);
    else
      f.state.compliance->solver().solve(r.force, du);
    benchmark::DoNotOptimize(du.data());
  }
}
BENCHMARK(BM_ResponseWholeMeshCorrection)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// The paper's response on the same contacts: hold every contact node (3 unit rows each) by the equality solve.
void BM_ResponsePaperHold(benchmark::State& state) {
  FrozenFrame& f = frozen();
  for (auto _ : state)
    benchmark::DoNotOptimize(physics::solve_equality(*f.state.compliance, f.held, f.u_free, 1e-9, state.range(0) != 0));
  state.counters["rows"] = static_cast<double>(f.held.size());
}
BENCHMARK(BM_ResponsePaperHold)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

}  // namespace
