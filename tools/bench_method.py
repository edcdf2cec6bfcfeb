#!/usr/bin/env python3
"""The corotational quasi-static solve's linear steps side by side (solver.method: "pcg", PCG on K_w preconditioned
by the lagged factorisation; "chord", one back-substitution on the lagged factorisation a step): each scene run
with the corotational model and each method `--runs` times, the methods alternating run by run, the lagged
factorisation on the second core as shipped scenes run it, headless with the exact intersection check.

usage: tools/bench_method.py [--runs 3] [--methods pcg,chord] [--tolerances 1e-3] [--bounds 0,4]
       [--reference-tolerance 1e-7] [--out docs/bench_method.csv] [--lumen build/lumen] SCENE.json ...

With --tolerances, each method runs at each solver.tolerance, and the error against a tightly converged run (PCG
at --reference-tolerance, once per scene, untimed) is reported: the largest difference over frames and probe
points of the probe points' displacements, relative to the largest reference displacement (probe_error_max), and
its median over frames (probe_error_median; max over runs). With --bounds, PCG also runs at each value of
solver.max_back_substitutions (the work bound of a frame's solve; 0 = none), with the same error against the
reference (which needs --tolerances).

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


def variant(path, method, tolerance=None, bound=0):
    """The scene at `path` with the corotational model, the given method and, when given, solver.tolerance and
    solver.max_back_substitutions (other solver keys kept)."""
    with open(path) as f:
        s = json.load(f)
    s["name"] = f"{s['name']}-{method}" + (f"-tol{tolerance:g}" if tolerance else "") + (f"-b{bound}" if bound else "")
    s["material"]["model"] = "corotational"
    s.setdefault("solver", {})["method"] = method
    if tolerance:
        s["solver"]["tolerance"] = tolerance
    if bound:
        s["solver"]["max_back_substitutions"] = bound
    return s


def probe_errors(run, reference):
    """Per frame the largest |d - d_ref| over the probe points, relative to the largest |d_ref| of the session
    (probe displacements)."""
    scale = max((math.hypot(*r) for g in reference["per_frame"] for r in g["probe_displacement_m"]), default=0.0)
    errors = [max((math.dist(d, r) for d, r in zip(f["probe_displacement_m"], g["probe_displacement_m"])), default=0.0)
              for f, g in zip(run["per_frame"], reference["per_frame"])]
    return [e / scale for e in errors] if scale > 0.0 else [0.0 for _ in errors]


def summarise(path, method, runs, tolerance=None, reference=None, bound=0):
    per = [r["per_frame"] for r in runs]
    pcr = [[f["physics_ms"] + f["collision_ms"] + f["response_ms"] for f in p] for p in per]
    med = lambda values: round(statistics.median(values), 3)
    tip = per[0][-1]["probe_displacement_m"]
    return {"scene": os.path.basename(path), "method": method, "tolerance": tolerance or "scene",
            "max_back_substitutions": bound,
            "probe_error_median": (round(max(statistics.median(probe_errors(r, reference)) for r in runs), 6)
                                   if reference else ""),
            "probe_error_max": round(max(max(probe_errors(r, reference)) for r in runs), 6) if reference else "",
            "runs": len(runs), "frames": len(per[0]),
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
    ap.add_argument("--tolerances", default="", help="comma-separated solver.tolerance values (default: the scene's)")
    ap.add_argument("--reference-tolerance", type=float, default=1e-7)
    ap.add_argument("--bounds", default="", help="comma-separated solver.max_back_substitutions values for PCG "
                    "(0 = none; default: the scene's)")
    a = ap.parse_args()
    methods = a.methods.split(",")
    bad = [m for m in methods if m not in METHODS]
    try:
        tolerances = [float(t) for t in a.tolerances.split(",")] if a.tolerances else [None]
    except ValueError:
        ap.error(f"--tolerances must be comma-separated numbers (got {a.tolerances!r})")
    try:
        bounds = [int(b) for b in a.bounds.split(",")] if a.bounds else [0]
    except ValueError:
        ap.error(f"--bounds must be comma-separated integers (got {a.bounds!r})")
    if bad or a.runs < 1 or any(t is not None and not t > 0 for t in tolerances) or any(b < 0 or b == 1 for b in bounds):
        ap.error(f"--methods must name {', '.join(METHODS)}, --runs be >= 1, --tolerances > 0 and --bounds 0 or >= 2 "
                 f"(got {a.methods!r}, {a.runs}, {a.tolerances!r}, {a.bounds!r})")
    # (The work bound is PCG's: chord runs unbounded.)
    cases = [(m, t, b) for t in tolerances for m in methods for b in (bounds if m == "pcg" else [0])]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for path in a.scenes:
            reference = None
            if a.tolerances:
                tight = variant(path, "pcg", a.reference_tolerance)
                tight["solver"]["max_iterations"] = 500
                tight["solver"]["background_factorisation"] = False
                reference = run_report(a.lumen, tight, tmp)
            runs = {c: [] for c in cases}
            for _ in range(a.runs):
                for m, t, b in cases:
                    runs[(m, t, b)].append(run_report(a.lumen, variant(path, m, t, b), tmp))
            for m, t, b in cases:
                rows.append(summarise(path, m, runs[(m, t, b)], t, reference, b))
                print(rows[-1], flush=True)
    tol_args = f" --tolerances {a.tolerances} --reference-tolerance {a.reference_tolerance:g}" if a.tolerances else ""
    tol_args += f" --bounds {a.bounds}" if a.bounds else ""
    header = [f"made by: tools/bench_method.py --runs {a.runs} --methods {a.methods}{tol_args} --out {a.out} "
              + " ".join(a.scenes),
              f"machine: {platform.machine()}, {os.cpu_count()} cores; ms = median over runs (methods alternating); "
              "counts = max over runs"]
    write_csv(a.out, header, rows)


if __name__ == "__main__":
    main()
