// Physics benchmarks on the paper mesh (20 x 26 x 3: 2160 nodes, 9360 tets), E 5000 Pa, nu 0.45, both ends fixed:
// assembly, factorisation, one back-substitution, the per-frame load path, compliance and contact solves.
#include <benchmark/benchmark.h>

#include <memory>
#include <random>
#include <vector>

#include "physics/compliance.hpp"
#include "physics/fem.hpp"
#include "physics/mesh.hpp"
#include "physics/surface_compliance.hpp"

namespace {

using namespace lumen;
using namespace lumen::physics;

// The paper model, built once.
struct PaperModel {
  TetMesh mesh = make_hollow_cylinder(HollowCylinderSpec{});
  LinearMaterial material{5000.0, 0.45};
  Eigen::SparseMatrix<double> K = assemble_stiffness(mesh, material);
  std::vector<int> fixed;
  std::unique_ptr<StaticSolver> solver;
  std::vector<int> inner_nodes;  // inner-wall node ids (540)
  std::unique_ptr<SurfaceCompliance> compliance;

  PaperModel() {
    fixed = mesh.node_set(kStartEnd);
    fixed.insert(fixed.end(), mesh.node_set(kStopEnd).begin(), mesh.node_set(kStopEnd).end());
    solver = std::make_unique<StaticSolver>(K, fixed);
    std::vector<char> on(mesh.n_nodes(), 0);
    for (int i = 0; i < mesh.surface(kInnerWall).size(); ++i) on[mesh.surface(kInnerWall).data()[i]] = 1;
    for (int v = 0; v < mesh.n_nodes(); ++v)
      if (on[v]) inner_nodes.push_back(v);
  }
  // Built on first use (about 1620 solves).
  SurfaceCompliance& inner_compliance() {
    if (!compliance) compliance = std::make_unique<SurfaceCompliance>(*solver, inner_nodes);
    return *compliance;
  }
  // Load points at the centroids of inner triangles spread along the tube.
  std::vector<LoadPoint> load_points(int m) const {
    std::vector<LoadPoint> pts(m);
    for (int p = 0; p < m; ++p) {
      const int t = static_cast<int>((p + 0.5) * mesh.surface(kInnerWall).rows() / m);
      for (int k = 0; k < 3; ++k) pts[p].node[k] = mesh.surface(kInnerWall)(t, k), pts[p].weight[k] = 1.0 / 3.0;
    }
    return pts;
  }
};

PaperModel& model() {
  static PaperModel m;
  return m;
}

void BM_PhysicsAssembleStiffness(benchmark::State& state) {
  const PaperModel& m = model();
  for (auto _ : state) benchmark::DoNotOptimize(assemble_stiffness(m.mesh, m.material));
}
BENCHMARK(BM_PhysicsAssembleStiffness)->Unit(benchmark::kMillisecond);

void BM_PhysicsFactorise(benchmark::State& state) {
  const PaperModel& m = model();
  for (auto _ : state) {
    StaticSolver s(m.K, m.fixed);
    benchmark::DoNotOptimize(s.n_free_dofs());
  }
  state.counters["L_nnz"] = static_cast<double>(m.solver->factor_nonzeros());
  state.counters["free_dofs"] = m.solver->n_free_dofs();
}
BENCHMARK(BM_PhysicsFactorise)->Unit(benchmark::kMillisecond);

// One back-substitution: the cost of a frame without precomputed responses, and of a contact correction.
void BM_PhysicsSolve(benchmark::State& state) {
  const PaperModel& m = model();
  Eigen::VectorXd f = Eigen::VectorXd::Zero(m.solver->n_dofs()), u;
  f[3 * m.mesh.surface(kInnerWall)(500, 0) + 1] = -0.05;
  for (auto _ : state) {
    m.solver->solve(f, u);
    benchmark::DoNotOptimize(u.data());
  }
}
BENCHMARK(BM_PhysicsSolve)->Unit(benchmark::kMicrosecond);

// The same on the factor's single-precision copy (the corotational solves' preconditioner), and its relative
// difference from the double solve.
void BM_PhysicsSolveSinglePrecision(benchmark::State& state) {
  const PaperModel& m = model();
  StaticSolver single(m.K, m.fixed);
  single.add_single_precision();
  Eigen::VectorXd f = Eigen::VectorXd::Zero(m.solver->n_dofs()), u, u_double;
  f[3 * m.mesh.surface(kInnerWall)(500, 0) + 1] = -0.05;
  for (auto _ : state) {
    single.solve_approximately(f, u);
    benchmark::DoNotOptimize(u.data());
  }
  m.solver->solve(f, u_double);
  state.counters["rel_diff"] = (u - u_double).norm() / u_double.norm();
}
BENCHMARK(BM_PhysicsSolveSinglePrecision)->Unit(benchmark::kMicrosecond);

// A QP step's solves on a factor of the nested-dissection analysis (the solved coupling's lagged Hessian):
// B^-1 r then B^-1 H^T lambda as two whole solves (arg 0), or split (arg 1): the forward half of r, the row nodes'
// displacements read and the contact forces on range(1) inner nodes added through their half columns (solved
// before timing), one backward half.
void BM_PhysicsQpStepSolves(benchmark::State& state) {
  const PaperModel& m = model();
  m.solver->prepare_nested_analysis();
  const StaticSolver nested = m.solver->refactorised_nested(m.K);
  const int touched = static_cast<int>(state.range(1));
  std::vector<int> nodes;
  for (int k = 0; k < touched; ++k) nodes.push_back(m.inner_nodes[(k * 7) % m.inner_nodes.size()]);
  SurfaceCompliance lazy(nested, m.inner_nodes, SurfaceCompliance::kBlockColumns, 0L, 0L);
  lazy.ensure_columns(nodes);
  const Eigen::VectorXd r = Eigen::VectorXd::Random(nested.n_dofs());
  Eigen::VectorXd fc = Eigen::VectorXd::Zero(nested.n_dofs()), du, dc;
  for (int v : nodes) fc.segment<3>(3 * v) = Eigen::Vector3d(0.0, 0.01, 0.0);
  std::vector<double> z;
  Eigen::Vector3d seen = Eigen::Vector3d::Zero();
  for (auto _ : state) {
    if (state.range(0) == 0) {
      nested.solve(r, du);
      for (int v : nodes) seen += du.segment<3>(3 * v);
      nested.solve(fc, dc);
      du += dc;
    } else {
      nested.half_forward(r, z);
      for (int v : nodes) seen += lazy.half_displacement(v, z);
      for (int v : nodes) lazy.add_half_force(v, fc.segment<3>(3 * v), z);
      nested.half_backward(z, du);
    }
    benchmark::DoNotOptimize(du.data());
    benchmark::DoNotOptimize(seen.data());
  }
  long entries = 0;
  for (int v : nodes) entries += lazy.half_entries(v);
  state.counters["half_entries"] = static_cast<double>(entries);
  state.counters["L_nnz"] = static_cast<double>(nested.factor_nonzeros());
}
BENCHMARK(BM_PhysicsQpStepSolves)
    ->Args({0, 20})->Args({1, 20})->Args({0, 80})->Args({1, 80})->Args({0, 150})->Args({1, 150})
    ->Unit(benchmark::kMicrosecond);

// The half columns of 32 inner nodes (StaticSolver::half_columns, a node's three at once): arg 0 on the rest
// solver (CHOLMOD's partial solves on its nested-dissection factor, one a DOF), arg 1 on a solver from
// refactorised_nested (one supernodal forward sweep over the node's paths in the elimination tree).
void BM_PhysicsHalfColumnsOfNodes(benchmark::State& state) {
  const PaperModel& m = model();
  m.solver->prepare_nested_analysis();
  const StaticSolver nested = m.solver->refactorised_nested(m.K);
  const StaticSolver& solver = state.range(0) == 0 ? *m.solver : nested;
  std::vector<int> index;
  std::vector<double> value;
  long entries = 0;
  for (auto _ : state) {
    entries = 0;
    for (int k = 0; k < 32; ++k) {
      const int v = m.inner_nodes[(k * 17) % m.inner_nodes.size()];
      solver.half_columns({3 * v, 3 * v + 1, 3 * v + 2}, index, value);
      entries += static_cast<long>(index.size());
    }
    benchmark::DoNotOptimize(value.data());
  }
  state.counters["rows_per_node"] = static_cast<double>(entries) / 32.0;
  state.SetItemsProcessed(state.iterations() * 32);
}
BENCHMARK(BM_PhysicsHalfColumnsOfNodes)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

void BM_PhysicsSolveMany(benchmark::State& state) {
  const PaperModel& m = model();
  const Eigen::MatrixXd F = Eigen::MatrixXd::Random(m.solver->n_dofs(), state.range(0));
  for (auto _ : state) benchmark::DoNotOptimize(m.solver->solve_many(F));
  state.SetItemsProcessed(state.iterations() * state.range(0));
}
BENCHMARK(BM_PhysicsSolveMany)->Arg(64)->Unit(benchmark::kMillisecond);

// The per-frame load path: u = U * forces for m load points.
void BM_PhysicsLoadResponseDisplacement(benchmark::State& state) {
  const PaperModel& m = model();
  const int np = static_cast<int>(state.range(0));
  const LoadResponse lr(*m.solver, m.load_points(np));
  Points forces = Points::Constant(np, 3, 0.01);
  Eigen::VectorXd u(m.solver->n_dofs());
  for (auto _ : state) {
    lr.displacement(forces, u);
    benchmark::DoNotOptimize(u.data());
  }
}
BENCHMARK(BM_PhysicsLoadResponseDisplacement)->Arg(1)->Arg(2)->Arg(4)->Unit(benchmark::kMicrosecond);

void BM_PhysicsLoadResponsePrecompute(benchmark::State& state) {
  const PaperModel& m = model();
  const auto pts = m.load_points(static_cast<int>(state.range(0)));
  for (auto _ : state) {
    LoadResponse lr(*m.solver, pts);
    benchmark::DoNotOptimize(lr.response().data());
  }
}
BENCHMARK(BM_PhysicsLoadResponsePrecompute)->Arg(2)->Unit(benchmark::kMillisecond);

// Dense compliance of the inner wall: 540 nodes, 1620 x 1620, in blocks of 64 columns.
void BM_PhysicsSurfaceComplianceBuild(benchmark::State& state) {
  PaperModel& m = model();
  for (auto _ : state) {
    SurfaceCompliance sc(*m.solver, m.inner_nodes);
    benchmark::DoNotOptimize(sc.matrix().data());
  }
}
BENCHMARK(BM_PhysicsSurfaceComplianceBuild)->Unit(benchmark::kMillisecond)->Iterations(2);

// Contact rows on the inner wall: vertex-face rows between nodes on opposite sides, all violated by 0.5 mm.
std::vector<ContactRow> contact_rows(const PaperModel& m, int count, std::mt19937& rng) {
  std::uniform_int_distribution<int> tri(0, static_cast<int>(m.mesh.surface(kInnerWall).rows()) - 1);
  std::vector<ContactRow> rows(count);
  for (ContactRow& r : rows) {
    const int t = tri(rng), s = tri(rng);
    r.node[0] = m.mesh.surface(kInnerWall)(s, 0), r.weight[0] = 1.0;
    for (int k = 0; k < 3; ++k) r.node[k + 1] = m.mesh.surface(kInnerWall)(t, k), r.weight[k + 1] = -1.0 / 3.0;
    r.n = Eigen::Vector3d(0.0, 1.0, 0.2).normalized();
    r.g = 5e-4;
  }
  return rows;
}

void BM_PhysicsContactLcp(benchmark::State& state) {
  PaperModel& m = model();
  SurfaceCompliance& sc = m.inner_compliance();
  std::mt19937 rng(1);
  const auto rows = contact_rows(m, static_cast<int>(state.range(0)), rng);
  const Eigen::VectorXd u_free = Eigen::VectorXd::Zero(m.solver->n_dofs());
  int pivots = 0;
  bool ok = true;
  for (auto _ : state) {
    const ContactResult r = solve_lcp(sc, rows, u_free);
    pivots = r.iterations;
    ok = ok && r.converged;
  }
  state.counters["pivots"] = pivots;
  state.counters["converged"] = ok;
}
BENCHMARK(BM_PhysicsContactLcp)->Arg(8)->Arg(32)->Arg(128)->Unit(benchmark::kMillisecond);

// The paper's response: hold k vertices at positions (3 rows each).
void BM_PhysicsContactEquality(benchmark::State& state) {
  PaperModel& m = model();
  SurfaceCompliance& sc = m.inner_compliance();
  const int k = static_cast<int>(state.range(0));
  std::vector<ContactRow> rows;
  for (int i = 0; i < k; ++i)
    for (int c = 0; c < 3; ++c) {
      ContactRow r;
      r.node[0] = m.inner_nodes[100 + 7 * i], r.weight[0] = 1.0;
      r.n = Eigen::Vector3d::Unit(c);
      r.g = 1e-4;
      rows.push_back(r);
    }
  const Eigen::VectorXd u_free = Eigen::VectorXd::Zero(m.solver->n_dofs());
  for (auto _ : state) benchmark::DoNotOptimize(solve_equality(sc, rows, u_free).lambda.data());
}
BENCHMARK(BM_PhysicsContactEquality)->Arg(6)->Arg(24)->Unit(benchmark::kMillisecond);

}  // namespace
