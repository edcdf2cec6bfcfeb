#!/usr/bin/env bash
# Google Benchmark micro-benchmarks committed as CSV (aggregates of 5 repetitions: mean, median, stddev, cv):
#   docs/bench_bvh.csv      BVH self-traversal vs all pairs of k-DOPs (broad phase and whole detect), k = 6..26
#   docs/bench_kernels.csv  CHOLMOD factorise/solve, precomputed load response, render draw, PNG, video, CCD kernels
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
bench="$root/build/lumen_benchmarks"
run() {  # filter, output
  local json tmp="$2.tmp"
  json="$(mktemp)"
  "$bench" --benchmark_filter="$1" --benchmark_repetitions=5 --benchmark_report_aggregates_only=true \
    --benchmark_format=json > "$json" 2>/dev/null
  python3 - "$json" "$1" > "$tmp" <<'PY'
import json, sys
data = json.load(open(sys.argv[1]))
rows = data["benchmarks"]
extra = sorted({k for r in rows for k in r if k not in ("name", "run_name", "run_type", "aggregate_name",
                "aggregate_unit", "family_index", "per_family_instance_index", "repetitions", "repetition_index",
                "threads", "iterations", "real_time", "cpu_time", "time_unit", "label")})
print(f"# made by: tools/bench_micro.sh (build/lumen_benchmarks --benchmark_filter='{sys.argv[2]}' --benchmark_repetitions=5)")
print(f"# machine: {data['context'].get('num_cpus')} cpus, {data['context'].get('mhz_per_cpu')} MHz")
print(",".join(["name", "aggregate", "real_time", "cpu_time", "time_unit", "label"] + extra))
for r in rows:
    print(",".join(str(v) for v in [r["run_name"], r.get("aggregate_name", ""), r["real_time"], r["cpu_time"],
                                    r["time_unit"], r.get("label", "")] + [r.get(k, "") for k in extra]))
PY
  rm -f "$json"
  mv "$tmp" "$2"
}
run 'SelfCollision|BroadPhase' "$root/docs/bench_bvh.csv"
run 'PhysicsSolve$|PhysicsFactorise|PhysicsLoadResponseDisplacement|RenderDraw|PngWrite|VideoEncode|BM_Ccd/' "$root/docs/bench_kernels.csv"
