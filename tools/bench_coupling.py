#!/usr/bin/env python3
"""How the contacts meet the corotational solve, side by side: two opposite tips (7 probe points each, 3 mm
radius, the study's and the reference's tip) pinch the paper tube shut at `--force` newtons per tip (ramped over
2 s, held 1 s, 120 frames), corotational quasi-static, self-collision on, headless with the exact intersection
check; each variant of collision.coupling ("correct", "carried"), solver.method ("pcg", "chord") and
solver.anderson_depth (0, 5) run `--runs` times, the lagged factorisation on the second core (as shipped scenes
run) unless --serial.

usage: tools/bench_coupling.py [--runs 1] [--force 0.16] [--couplings correct,carried] [--anderson 0,5]
       [--tangents warped] [--methods pcg,chord] [--serial] [--out docs/bench_coupling.csv] [--lumen build/lumen]

Per variant (ms: median over runs of each run's statistic; counts: max over runs): physics median / p99 ms,
collision + response median ms, physics + collision + response per frame median / p99 / max ms, frames whose nonlinear solve converged, nonlinear iterations over the session,
fallback frames, frames with intersecting pairs, total contact force at the last frame (N), and the top tip's
mean displacement at the last frame (mm, downwards), the largest contact residual over the frames (complementarity,
metres).
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

TIP_RADIUS = 0.003   # metres: the tip disk's radius
TIP_POINTS = 7       # its centre and 6 rim points
PROBE_Z = 0.05       # metres: mid-length of the paper tube


def tips_scene(force, coupling, anderson, tangent, method="pcg", serial=True):
    """The paper tube pinched by two 7-point tips, as a scene dict."""
    root = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
    with open(os.path.join(root, "scenes", "hard", "closure-5x-force.json")) as f:
        s = json.load(f)
    s["name"] = f"tips-{coupling}-aa{anderson}-{tangent}-{method}"
    s["material"]["model"] = "corotational"
    s["solver"] = {"background_factorisation": not serial, "anderson_depth": anderson, "tangent": tangent,
                   "method": method}
    s["collision"]["coupling"] = coupling
    # Tip points at the mean radius of the faceted outer wall (20 facets), as tools/study/study.cpp places them.
    r = 0.013 * 0.5 * (1.0 + math.cos(math.pi / s["mesh"]["segments_around"]))
    probes = []
    for side, sign in (("top", 1.0), ("bottom", -1.0)):
        for k in range(TIP_POINTS):
            arc = 0.0 if k == 0 else TIP_RADIUS * math.cos(math.pi / 3.0 * (k - 1))
            dz = 0.0 if k == 0 else TIP_RADIUS * math.sin(math.pi / 3.0 * (k - 1))
            a = math.pi / 2.0 - arc / r
            f = [0.0, -sign * force / TIP_POINTS, 0.0]
            probes.append({"name": f"{side}{k}", "point": [r * math.cos(a), sign * r * math.sin(a), PROBE_Z + dz],
                           "track": [{"t": 0.0, "force": [0.0, 0.0, 0.0]}, {"t": 2.0, "force": f},
                                     {"t": 3.0, "force": f}]})
    s["probes"] = probes
    return s


def summarise(coupling, anderson, tangent, method, force, runs):
    per = [r["per_frame"] for r in runs]
    pcr = [[f["physics_ms"] + f["collision_ms"] + f["response_ms"] for f in p] for p in per]
    med = lambda stage, st: round(statistics.median(r["stages"][stage][st] for r in runs), 3)
    last = per[0][-1]
    return {"coupling": coupling, "method": method, "anderson_depth": anderson, "tangent": tangent,
            "force_per_tip_n": force,
            "runs": len(runs),
            "frames": len(per[0]), "physics_median_ms": med("physics", "median_ms"),
            "physics_p99_ms": med("physics", "p99_ms"),
            "collision_response_median_ms": round(statistics.median(
                r["stages"]["collision"]["median_ms"] + r["stages"]["response"]["median_ms"] for r in runs), 3),
            "pcr_median_ms": round(statistics.median(percentile(p, 50) for p in pcr), 3),
            "pcr_p99_ms": round(statistics.median(percentile(p, 99) for p in pcr), 3),
            "pcr_max_ms": round(statistics.median(max(p) for p in pcr), 3),
            "converged_frames": min(sum(f["physics_converged"] for f in p) for p in per),
            "nonlinear_iterations": max(sum(f["physics_iterations"] for f in p) for p in per),
            "fallback_frames": max(r["fallback_frames"] for r in runs),
            "frames_with_intersections": max(r["frames_with_intersections"] for r in runs),
            "contact_force_end_n": round(last["contact_force_n"], 4),
            "top_tip_displacement_end_mm": round(
                -1000.0 * sum(p[1] for p in last["probe_displacement_m"][:TIP_POINTS]) / TIP_POINTS, 3),
            "contact_residual_max_m": max(max(f["contact_residual_m"] for f in p) for p in per)}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=1)
    ap.add_argument("--force", type=float, default=0.16)
    ap.add_argument("--out", default="docs/bench_coupling.csv")
    ap.add_argument("--lumen", default="build/lumen")
    ap.add_argument("--couplings", default="correct,carried", help="comma-separated collision.coupling values")
    ap.add_argument("--anderson", default="0,5", help="comma-separated solver.anderson_depth values")
    ap.add_argument("--tangents", default="warped", help="comma-separated solver.tangent values")
    ap.add_argument("--methods", default="pcg", help="comma-separated solver.method values")
    ap.add_argument("--serial", action="store_true", help="factorise inside the solve (reproducible, slower)")
    a = ap.parse_args()
    if a.runs < 1 or not a.force > 0.0:
        ap.error(f"--runs must be >= 1 and --force > 0 (got --runs {a.runs}, --force {a.force})")
    couplings, tangents, methods = a.couplings.split(","), a.tangents.split(","), a.methods.split(",")
    for option, values, allowed in (("--couplings", couplings, ("correct", "carried")),
                                    ("--tangents", tangents, ("warped", "projected", "exact")),
                                    ("--methods", methods, ("pcg", "chord"))):
        bad = [v for v in values if v not in allowed]
        if bad:
            ap.error(f"{option} must name {', '.join(allowed)} (got {bad[0]!r})")
    try:
        andersons = [int(v) for v in a.anderson.split(",")]
    except ValueError:
        ap.error(f"--anderson must be comma-separated integers (got {a.anderson!r})")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for coupling in couplings:
            for method in methods:
                for tangent in tangents:
                    for anderson in andersons:
                        scene = tips_scene(a.force, coupling, anderson, tangent, method, a.serial)
                        runs = [run_report(a.lumen, scene, tmp) for _ in range(a.runs)]
                        rows.append(summarise(coupling, anderson, tangent, method, a.force, runs))
                        print(rows[-1], flush=True)
    header = [f"made by: tools/bench_coupling.py --runs {a.runs} --force {a.force} --couplings {a.couplings} "
              f"--anderson {a.anderson} --tangents {a.tangents} --methods {a.methods}{' --serial' if a.serial else ''} "
              f"--out {a.out}",
              f"machine: {platform.machine()}, {os.cpu_count()} cores; ms = median over runs; counts = max over runs"]
    write_csv(a.out, header, rows)


if __name__ == "__main__":
    main()
