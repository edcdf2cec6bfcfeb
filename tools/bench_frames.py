#!/usr/bin/env python3
"""Frame-time benchmark of shipped scenes: runs `lumen bench SCENE --json` R times per scene and writes a CSV
of the per-stage medians/p95/p99/max (the median over the R runs of each statistic) and over-budget frames.

usage: tools/bench_frames.py [--runs 5] [--out docs/bench_frames.csv] [--lumen build/lumen] SCENE.json ...
"""
import argparse
import json
import os
import platform
import statistics
import subprocess
import sys

from csv_out import write_csv

STAGES = ["input", "physics", "collision", "response", "render", "total"]
STATS = ["median_ms", "p95_ms", "p99_ms", "max_ms"]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scenes", nargs="+")
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--out", default="docs/bench_frames.csv")
    ap.add_argument("--lumen", default="build/lumen")
    ap.add_argument("--extra", default="", help="extra arguments for lumen bench")
    a = ap.parse_args()
    rows = []
    for scene in a.scenes:
        runs = []
        for _ in range(a.runs):
            cmd = [a.lumen, "bench", scene, "--json"] + a.extra.split()
            out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
            runs.append(json.loads(out))
        r0 = runs[0]
        row = {"scene": r0["scene"], "mesh_source": r0["mesh"].get("source", ""),
               "nodes": r0["mesh"]["nodes"], "tets": r0["mesh"]["tets"],
               "inner_triangles": r0["mesh"]["inner_triangles"], "frames": r0["frames"], "runs": a.runs,
               "render": r0["render"]["enabled"], "width": r0["render"]["width"], "height": r0["render"]["height"],
               "over_budget_frames_max": max(r["over_budget_frames"] for r in runs),
               "fallback_frames_max": max(r.get("fallback_frames", 0) for r in runs),
               # The mesh: its build time at load (median over runs) and its worst dihedral angle.
               "mesh_build_ms": round(statistics.median(r["mesh"].get("build_ms", float("nan")) for r in runs), 3),
               "min_dihedral_deg": r0["mesh"].get("min_dihedral_deg", {}).get("min", float("nan"))}
        for s in STAGES:
            for st in STATS:
                row[f"{s}_{st}"] = round(statistics.median(r["stages"][s][st] for r in runs), 4)
        rows.append(row)
        print(f"{row['scene']}: total median {row['total_median_ms']} ms, p99 {row['total_p99_ms']} ms, "
              f"physics median {row['physics_median_ms']} ms, over budget (max of runs) {row['over_budget_frames_max']}",
              file=sys.stderr)
    write_csv(a.out, [f"made by: tools/bench_frames.py --runs {a.runs} {' '.join(a.scenes)}"
                      f"{' --extra ' + repr(a.extra) if a.extra else ''}",
                      f"machine: {platform.machine()}, {os.cpu_count()} cores; statistic = median over runs of each per-run statistic"],
              rows)


if __name__ == "__main__":
    main()
