// Elementary CCD tests over the dev-set query files (tests/data/ccd), per file and kind: the time per query
// (items/s = queries/s) at gap 0 and at a gap of 1e-4 (the response's use), and the slowest query.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <map>
#include <string>
#include <vector>

#include "collision/ccd.hpp"
#include "collision/ccd_queries.hpp"

namespace {

using lumen::collision::CcdHit;
using lumen::collision::CcdQuery;

// The dev-set data in the repository (LUMEN_TEST_DATA_DIR = tests/data, set in tools/bench/CMakeLists.txt).
const std::string kDataDir = std::string(LUMEN_TEST_DATA_DIR) + "/ccd/";

// The queries of one kind in one file, read once.
const std::vector<CcdQuery>& queries(const std::string& file, bool edge_edge) {
  static std::map<std::string, std::vector<CcdQuery>> cache;
  const std::string key = file + (edge_edge ? "/ee" : "/vf");
  auto it = cache.find(key);
  if (it == cache.end()) {
    std::vector<CcdQuery> all = lumen::collision::read_ccd_queries(kDataDir + file);
    all.erase(std::remove_if(all.begin(), all.end(), [&](const CcdQuery& q) { return q.edge_edge != edge_edge; }),
              all.end());
    it = cache.emplace(key, std::move(all)).first;
  }
  return it->second;
}

bool run(const CcdQuery& q, double gap, CcdHit* hit) {
  const auto* a = q.x0;
  const auto* b = q.x1;
  return q.edge_edge
             ? lumen::collision::edge_edge_ccd(a[0], a[1], a[2], a[3], b[0], b[1], b[2], b[3], gap, hit)
             : lumen::collision::vertex_face_ccd(a[0], a[1], a[2], a[3], b[0], b[1], b[2], b[3], gap, hit);
}

// All queries of a file and kind per iteration; counters: contacts, mean boxes, and the slowest query
// (ns; the least over the iterations of each iteration's slowest, which drops preempted runs).
void BM_Ccd(benchmark::State& state, const std::string& file, bool edge_edge, double gap) {
  const std::vector<CcdQuery>& qs = queries(file, edge_edge);
  long contacts = 0, boxes = 0;
  double slowest = 1e300;
  for (auto _ : state) {
    contacts = boxes = 0;
    double iteration_slowest = 0.0;
    for (const CcdQuery& q : qs) {
      CcdHit hit;
      const auto t0 = std::chrono::steady_clock::now();
      const bool c = run(q, gap, &hit);
      const double ns = std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - t0).count();
      iteration_slowest = std::max(iteration_slowest, ns);
      contacts += c;
      boxes += hit.boxes;
    }
    slowest = std::min(slowest, iteration_slowest);
  }
  state.SetItemsProcessed(state.iterations() * static_cast<long>(qs.size()));
  state.counters["contacts"] = static_cast<double>(contacts);
  state.counters["boxes_per_query"] = static_cast<double>(boxes) / static_cast<double>(qs.size());
  state.counters["slowest_ns"] = slowest;
}

BENCHMARK_CAPTURE(BM_Ccd, handcrafted_vf, "handcrafted.csv", false, 0.0)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Ccd, handcrafted_ee, "handcrafted.csv", true, 0.0)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Ccd, simulation_vf, "simulation.csv", false, 0.0)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Ccd, simulation_ee, "simulation.csv", true, 0.0)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Ccd, simulation_vf_gap1e-4, "simulation.csv", false, 1e-4)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Ccd, simulation_ee_gap1e-4, "simulation.csv", true, 1e-4)->Unit(benchmark::kMillisecond);

}  // namespace
