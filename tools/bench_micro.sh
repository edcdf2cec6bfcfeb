#!/usr/bin/env bash
# Google Benchmark micro-benchmarks committed as CSV (median/mean/stddev of 5 repetitions):
#   docs/bench_bvh.csv      BVH self-traversal vs all pairs of k-DOPs (broad phase and whole detect), k = 6..26
#   docs/bench_kernels.csv  CHOLMOD solve, precomputed load response, render draw, PNG, video, CCD kernels
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
bench="$root/build/lumen_benchmarks"
run() {  # filter, output
  local tmp="$2.tmp"
  { echo "# made by: tools/bench_micro.sh (build/lumen_benchmarks --benchmark_filter='$1' --benchmark_repetitions=5)"
    "$bench" --benchmark_filter="$1" --benchmark_repetitions=5 --benchmark_report_aggregates_only=true \
      --benchmark_format=csv 2>/dev/null; } > "$tmp"
  mv "$tmp" "$2"
}
run 'SelfCollision|BroadPhase' "$root/docs/bench_bvh.csv"
run 'PhysicsSolve$|PhysicsFactorise|PhysicsLoadResponseDisplacement|RenderDraw|PngWrite|VideoEncode|BM_Ccd/' "$root/docs/bench_kernels.csv"
