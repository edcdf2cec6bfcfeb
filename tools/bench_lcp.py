#!/usr/bin/env python3
"""The constraint response's LCP solvers side by side: each scene run with collision.lcp "active_set" (exact) and
"nncg" (iterative, warm-started, sweep budget), headless with the exact intersection check on every frame.

usage: tools/bench_lcp.py [--runs 3] [--sweeps 200] [--out docs/bench_lcp.csv] [--lumen build/lumen] SCENE.json ...

Per scene and solver (statistic = median over the runs of each per-run statistic; counts = max over runs): the
response and collision stage median / p99 ms, the largest number of contacts in a frame, the contact solves'
iterations per frame (pivots / rounds for the active set, sweeps for NNCG: median and max over frames with
contacts), the largest contact residual (metres), fallback frames, frames with intersecting pairs, and the
largest difference of the total contact force per frame from the active-set run of the same scene (relative to
its largest total force).
"""
import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile

from csv_out import write_csv


def run_once(lumen, scene_path, out_dir):
    subprocess.run([lumen, "run", scene_path, "--no-render", "--check", "--out", out_dir], check=True,
                   capture_output=True, text=True)
    with open(os.path.join(out_dir, "report.json")) as f:
        return json.load(f)


def variant(scene_path, lcp, sweeps, tmp):
    with open(scene_path) as f:
        s = json.load(f)
    s.setdefault("collision", {})["lcp"] = lcp
    if lcp == "nncg":
        s["collision"]["lcp_sweeps"] = sweeps
    path = os.path.join(tmp, f"{s['name']}-{lcp}.json")
    with open(path, "w") as f:
        json.dump(s, f)
    return path, s["name"]


def summarise(name, lcp, runs, reference):
    per = [r["per_frame"] for r in runs]
    with_contacts = [f for f in per[0] if f["contacts"] > 0]
    force = [f["contact_force_n"] for f in per[0]]
    row = {"scene": name, "lcp": lcp, "runs": len(runs), "frames": len(per[0]),
           "max_contacts": max(max(f["contacts"] for f in p) for p in per)}
    for stage in ["response", "collision"]:
        for st in ["median_ms", "p99_ms"]:
            row[f"{stage}_{st}"] = round(statistics.median(r["stages"][stage][st] for r in runs), 4)
    its = [f["lcp_iterations"] for f in with_contacts] or [0]
    row["lcp_iterations_median"] = statistics.median(its)
    row["lcp_iterations_max"] = max(its)
    row["max_contact_residual_m"] = max(max(f["contact_residual_m"] for f in p) for p in per)
    row["fallback_frames"] = max(r["fallback_frames"] for r in runs)
    row["frames_with_intersections"] = max(r["frames_with_intersections"] for r in runs)
    if reference is not None:
        scale = max(max(reference), 1e-12)
        row["contact_force_diff_rel"] = max(abs(a - b) for a, b in zip(force, reference)) / scale
    else:
        row["contact_force_diff_rel"] = 0.0
    return row, force


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scenes", nargs="+")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--sweeps", type=int, default=200)
    ap.add_argument("--out", default="docs/bench_lcp.csv")
    ap.add_argument("--lumen", default="build/lumen")
    a = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for scene in a.scenes:
            reference = None
            for lcp in ["active_set", "nncg"]:
                path, name = variant(scene, lcp, a.sweeps, tmp)
                runs = [run_once(a.lumen, path, os.path.join(tmp, f"out-{name}-{lcp}-{i}")) for i in range(a.runs)]
                row, force = summarise(name, lcp, runs, reference)
                if lcp == "active_set":
                    reference = force
                rows.append(row)
                print(f"{name} {lcp}: response median {row['response_median_ms']} ms p99 {row['response_p99_ms']} ms, "
                      f"max contacts {row['max_contacts']}, fallbacks {row['fallback_frames']}, "
                      f"intersecting frames {row['frames_with_intersections']}, "
                      f"max residual {row['max_contact_residual_m']:.3g} m", file=sys.stderr)
    write_csv(a.out, [f"made by: tools/bench_lcp.py --runs {a.runs} --sweeps {a.sweeps} {' '.join(a.scenes)}",
                      f"machine: {platform.machine()}, {os.cpu_count()} cores; ms = median over runs; counts = max over runs"],
              rows)


if __name__ == "__main__":
    main()
