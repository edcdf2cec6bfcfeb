#!/usr/bin/env python3
"""The corotational quasi-static solve's linear steps side by side (solver.method: "pcg", PCG on K_w preconditioned
by the lagged factorisation; "chord", one back-substitution on the lagged factorisation a step): each scene run
with the corotational model and each method `--runs` times, the methods alternating run by run, the lagged
factorisation on the second core as shipped scenes run it, headless with the exact intersection check.

usage: tools/bench_method.py [--runs 3] [--methods pcg,chord] [--out docs/bench_method.csv] [--lumen build/lumen]
       SCENE.json ...

Per scene and method (ms: median over runs of each run's statistic; counts: max over runs): physics median / p99 /
max, physics + collision + response per frame median / p99, frames whose nonlinear solve converged, nonlinear
iterations and back-substitutions (cg_iterations) over the session, fallback frames, frames with intersecting
pairs, and the first probe point's displacement at the last frame (mm, its length).
"""
import argparse
import json
import math
import os
import platform
import statistics
import tempfile

from csv_out import write_csv
from session_run import percentile, run_report

METHODS = ("pcg", "chord")  # solver.method's values


def variant(path, method):
    """The scene at `path` with the corotational model and the given method (other solver keys kept)."""
    with open(path) as f:
        s = json.load(f)
    s["name"] = f"{s['name']}-{method}"
    s["material"]["model"] = "corotational"
    s.setdefault("solver", {})["method"] = method
    return s


def summarise(path, method, runs):
    per = [r["per_frame"] for r in runs]
    pcr = [[f["physics_ms"] + f["collision_ms"] + f["response_ms"] for f in p] for p in per]
    med = lambda values: round(statistics.median(values), 3)
    tip = per[0][-1]["probe_displacement_m"]
    return {"scene": os.path.basename(path), "method": method, "runs": len(runs), "frames": len(per[0]),
            "physics_median_ms": med(r["stages"]["physics"]["median_ms"] for r in runs),
            "physics_p99_ms": med(r["stages"]["physics"]["p99_ms"] for r in runs),
            "physics_max_ms": med(r["stages"]["physics"]["max_ms"] for r in runs),
            "pcr_median_ms": med(percentile(p, 50) for p in pcr),
            "pcr_p99_ms": med(percentile(p, 99) for p in pcr),
            "converged_frames": min(sum(f["physics_converged"] for f in p) for p in per),
            "nonlinear_iterations": max(sum(f["physics_iterations"] for f in p) for p in per),
            "back_substitutions": max(sum(f["cg_iterations"] for f in p) for p in per),
            "fallback_frames": max(r["fallback_frames"] for r in runs),
            "frames_with_intersections": max(r["frames_with_intersections"] for r in runs),
            "probe_displacement_end_mm": round(1000.0 * math.sqrt(sum(c * c for c in tip[0])), 3) if tip else ""}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scenes", nargs="+")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--methods", default="pcg,chord", help="comma-separated solver.method values")
    ap.add_argument("--out", default="docs/bench_method.csv")
    ap.add_argument("--lumen", default="build/lumen")
    a = ap.parse_args()
    methods = a.methods.split(",")
    bad = [m for m in methods if m not in METHODS]
    if bad or a.runs < 1:
        ap.error(f"--methods must name {', '.join(METHODS)} and --runs be >= 1 (got {a.methods!r}, {a.runs})")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for path in a.scenes:
            runs = {m: [] for m in methods}
            for _ in range(a.runs):
                for m in methods:
                    runs[m].append(run_report(a.lumen, variant(path, m), tmp))
            for m in methods:
                rows.append(summarise(path, m, runs[m]))
                print(rows[-1], flush=True)
    header = [f"made by: tools/bench_method.py --runs {a.runs} --methods {a.methods} --out {a.out} "
              + " ".join(a.scenes),
              f"machine: {platform.machine()}, {os.cpu_count()} cores; ms = median over runs (methods alternating); "
              "counts = max over runs"]
    write_csv(a.out, header, rows)


if __name__ == "__main__":
    main()
