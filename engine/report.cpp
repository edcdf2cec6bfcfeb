#include "engine/report.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace lumen::engine {

const char* stage_name(int stage) {
  static const char* names[kStageCount] = {"input", "physics", "collision", "response", "render", "total"};
  return names[stage];
}

StageSummary summarize(std::vector<double> v) {
  StageSummary s;
  if (v.empty()) return s;
  std::sort(v.begin(), v.end());
  // Interpolated quantile q in [0, 1].
  auto q = [&](double p) {
    double pos = p * (v.size() - 1);
    size_t i = static_cast<size_t>(std::floor(pos));
    size_t j = std::min(i + 1, v.size() - 1);
    return v[i] + (pos - i) * (v[j] - v[i]);
  };
  s.median_ms = q(0.5);
  s.p95_ms = q(0.95);
  s.p99_ms = q(0.99);
  s.max_ms = v.back();
  return s;
}

void write_json_file(const std::string& path, const nlohmann::json& j) { write_text_file(path, j.dump(1) + "\n"); }

void write_text_file(const std::string& path, const std::string& text) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw std::runtime_error(path + ": cannot write");
    out << text;
    out.flush();
    if (!out) {
      std::filesystem::remove(tmp);
      throw std::runtime_error(path + ": write failed");
    }
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    std::filesystem::remove(tmp);
    throw std::runtime_error(path + ": cannot rename temporary file: " + ec.message());
  }
}

nlohmann::json stages_json(const std::vector<FrameRecord>& frames) {
  nlohmann::json out = nlohmann::json::object();
  for (int s = 0; s < kStageCount; ++s) {
    std::vector<double> v;
    v.reserve(frames.size());
    for (const auto& f : frames) v.push_back(f.ms[s]);
    StageSummary sum = summarize(v);
    out[stage_name(s)] = {{"median_ms", sum.median_ms}, {"p95_ms", sum.p95_ms}, {"p99_ms", sum.p99_ms}, {"max_ms", sum.max_ms}};
  }
  return out;
}

std::string format_stage_table(const std::vector<FrameRecord>& frames, double budget_ms) {
  std::ostringstream o;
  char line[160];
  std::snprintf(line, sizeof line, "%-10s %10s %10s %10s %10s\n", "stage", "median_ms", "p95_ms", "p99_ms", "max_ms");
  o << line;
  const nlohmann::json st = stages_json(frames);
  for (int s = 0; s < kStageCount; ++s) {
    const auto& j = st.at(stage_name(s));
    std::snprintf(line, sizeof line, "%-10s %10.3f %10.3f %10.3f %10.3f\n", stage_name(s), j["median_ms"].get<double>(),
                  j["p95_ms"].get<double>(), j["p99_ms"].get<double>(), j["max_ms"].get<double>());
    o << line;
  }
  long over = std::count_if(frames.begin(), frames.end(), [](const FrameRecord& f) { return f.over_budget; });
  std::snprintf(line, sizeof line, "frames %zu, budget %.1f ms, over budget %ld\n", frames.size(), budget_ms, over);
  o << line;
  return o.str();
}

nlohmann::json frame_json(const FrameRecord& r) {
  nlohmann::json j;
  j["frame"] = r.frame;
  j["t"] = r.t;
  for (int s = 0; s < kStageCount; ++s) j[std::string(stage_name(s)) + "_ms"] = r.ms[s];
  j["over_budget"] = r.over_budget;
  j["bv_overlaps"] = r.bv_overlaps;
  j["full_detection"] = r.full_detection;
  j["first_contacts"] = r.first_contacts;
  j["feature_tests"] = r.feature_tests;
  j["contacts"] = r.contacts;
  j["response_iterations"] = r.response_iterations;
  j["fallback"] = r.fallback;
  j["contact_rows_capped"] = r.contact_rows_capped;
  j["fallback_kept"] = r.fallback_kept;
  j["interior_deferred"] = r.interior_deferred;
  j["interior_wait_ms"] = r.interior_wait_ms;
  if (r.intersecting_pairs >= 0) j["intersecting_pairs"] = r.intersecting_pairs;
  if (r.instrument_intersecting_pairs >= 0) j["instrument_intersecting_pairs"] = r.instrument_intersecting_pairs;
  j["inverted_elements"] = r.inverted_elements;
  j["numerical_failure"] = r.numerical_failure;
  j["bad_input"] = r.bad_input;
  j["physics_iterations"] = r.physics_iterations;
  j["physics_converged"] = r.physics_converged;
  j["physics_diverged"] = r.physics_diverged;
  j["refactorisations"] = r.refactorisations;
  j["tangent_fallbacks"] = r.tangent_fallbacks;
  j["cg_iterations"] = r.cg_iterations;
  j["truncated_steps"] = r.truncated_steps;
  j["preconditioner_failures"] = r.preconditioner_failures;
  j["twist_degrees"] = r.twist_degrees;
  j["kinetic_energy_j"] = r.kinetic_energy;
  j["contact_force_n"] = r.contact_force;
  j["contact_residual_m"] = r.contact_residual;
  j["lcp_iterations"] = r.lcp_iterations;
  j["lcp_converged"] = r.lcp_converged;
  j["equilibrium_steps"] = r.equilibrium_steps;
  j["equilibrium_backtracks"] = r.equilibrium_backtracks;
  j["equilibrium_residual"] = r.equilibrium_residual;
  j["max_displacement_m"] = r.max_displacement;
  nlohmann::json re = nlohmann::json::array();
  for (const auto& f : r.reactions) re.push_back({f.x(), f.y(), f.z()});
  j["reaction_force_n"] = re;
  nlohmann::json pd = nlohmann::json::array();
  for (const auto& d : r.probe_displacement) pd.push_back({d.x(), d.y(), d.z()});
  j["probe_displacement_m"] = pd;
  // Instruments: pose (rotation [w, x, y, z]), the contacts' force and torque on each, its contact rows.
  nlohmann::json tools = nlohmann::json::array();
  for (const InstrumentRecord& in : r.instruments) {
    const Eigen::Quaterniond& q = in.rotation;
    tools.push_back({{"name", in.name},
                     {"position", {in.position.x(), in.position.y(), in.position.z()}},
                     {"rotation", {q.w(), q.x(), q.y(), q.z()}},
                     {"force_n", {in.force.x(), in.force.y(), in.force.z()}},
                     {"torque_nm", {in.torque.x(), in.torque.y(), in.torque.z()}},
                     {"contacts", in.contacts},
                     {"opening", in.opening},
                     {"held_nodes", in.held_nodes},
                     {"stiffness_n_per_m", std::vector<double>(in.stiffness.data(), in.stiffness.data() + 9)}});
  }
  j["instruments"] = tools;
  return j;
}

std::string positions_csv(const Points& x) {
  std::string out;
  char line[96];
  for (Eigen::Index i = 0; i < x.rows(); ++i) {
    std::snprintf(line, sizeof line, "%.17g,%.17g,%.17g\n", x(i, 0), x(i, 1), x(i, 2));
    out += line;
  }
  return out;
}

}  // namespace lumen::engine
