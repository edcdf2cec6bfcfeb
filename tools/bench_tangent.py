#!/usr/bin/env python3
"""The corotational solve's linear-step operator side by side (solver.tangent: "warped", "projected", "exact")
on the shipped corotational scenes and the hard cases run with the corotational model, headless with the
exact intersection check, deterministic (background_factorisation false), each variant `--runs` times.

usage: tools/bench_tangent.py [--runs 1] [--tangents warped,projected,exact] [--scenes a.json,b.json]
       [--out docs/bench_tangent.csv] [--lumen build/lumen]

Per scene and tangent (ms: median over runs of each run's statistic; counts: max over runs): physics median /
p99 ms, whole-frame median / p99 ms (no render), frames whose nonlinear solve converged, nonlinear iterations,
exact-tangent fallbacks, PCG iterations and truncated (negative-curvature) CG solves over the session,
contact-response fallback frames, frames with intersecting pairs, and the largest node displacement at the last
frame (mm). (docs/bench_tangent.csv predates the cg_iterations and truncated_steps columns.)
"""
import argparse
import json
import os
import platform
import statistics
import tempfile

from csv_out import write_csv
from session_run import run_report

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
TANGENTS = ("warped", "projected", "exact")  # solver.tangent's values
# The scenes run by default, each with material.model set to corotational.
DEFAULT_SCENES = ["scenes/paper-press-corotational.json", "scenes/hard/twist-180-corotational.json",
                  "scenes/hard/closure-5x-force.json", "scenes/hard/inverting-point-force.json",
                  "scenes/hard/bent-tube-contact.json"]


def variant(path, tangent):
    """The scene at `path` with the corotational model, deterministic solves and the given tangent."""
    with open(os.path.join(ROOT, path)) as f:
        s = json.load(f)
    s["name"] = f"{s['name']}-{tangent}"
    s["material"]["model"] = "corotational"
    s.setdefault("solver", {})
    s["solver"]["background_factorisation"] = False
    s["solver"]["tangent"] = tangent
    return s


def summarise(path, tangent, runs):
    per = [r["per_frame"] for r in runs]
    med = lambda stage, st: round(statistics.median(r["stages"][stage][st] for r in runs), 3)
    return {"scene": os.path.basename(path), "tangent": tangent, "runs": len(runs), "frames": len(per[0]),
            "physics_median_ms": med("physics", "median_ms"), "physics_p99_ms": med("physics", "p99_ms"),
            "total_median_ms": med("total", "median_ms"), "total_p99_ms": med("total", "p99_ms"),
            "converged_frames": min(sum(f["physics_converged"] for f in p) for p in per),
            "nonlinear_iterations": max(sum(f["physics_iterations"] for f in p) for p in per),
            "tangent_fallbacks": max(sum(f["tangent_fallbacks"] for f in p) for p in per),
            "cg_iterations": max(sum(f["cg_iterations"] for f in p) for p in per),
            "truncated_steps": max(sum(f["truncated_steps"] for f in p) for p in per),
            "fallback_frames": max(r["fallback_frames"] for r in runs),
            "frames_with_intersections": max(r["frames_with_intersections"] for r in runs),
            "max_displacement_end_mm": round(1000.0 * per[0][-1]["max_displacement_m"], 4)}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=1)
    ap.add_argument("--tangents", default="warped,projected,exact", help="comma-separated solver.tangent values")
    ap.add_argument("--scenes", default=",".join(DEFAULT_SCENES), help="comma-separated scene files (from the root)")
    ap.add_argument("--out", default="docs/bench_tangent.csv")
    ap.add_argument("--lumen", default="build/lumen")
    a = ap.parse_args()
    if a.runs < 1:
        ap.error(f"--runs must be >= 1 (got {a.runs})")
    bad = [t for t in a.tangents.split(",") if t not in TANGENTS]
    if bad:
        ap.error(f"--tangents must name {', '.join(TANGENTS)} (got {bad[0]!r})")
    missing = [p for p in a.scenes.split(",") if not os.path.isfile(os.path.join(ROOT, p))]
    if missing:
        ap.error(f"--scenes: no such scene file {missing[0]!r}")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for path in a.scenes.split(","):
            for tangent in a.tangents.split(","):
                scene = variant(path, tangent)
                runs = [run_report(a.lumen, scene, tmp) for _ in range(a.runs)]
                rows.append(summarise(path, tangent, runs))
                print(rows[-1], flush=True)
    header = [f"made by: tools/bench_tangent.py --runs {a.runs} --tangents {a.tangents} --scenes {a.scenes} "
              f"--out {a.out}",
              f"machine: {platform.machine()}, {os.cpu_count()} cores; ms = median over runs; counts = max over runs"]
    write_csv(a.out, header, rows)


if __name__ == "__main__":
    main()
