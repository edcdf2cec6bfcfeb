#!/usr/bin/env python3
"""What instrument contact costs a frame: each instrument scene against its twin without instruments, side by side.

usage: tools/bench_instrument_overhead.py [--runs 3] [--out docs/bench_instrument_overhead.csv] [--lumen build/lumen]
                                          SCENE.json ...

The twin is the same scene (mesh, material, self-collision, render) with the instruments replaced by point
probes that apply, frame by frame, the force each instrument put on the organ in a first run of the scene (minus
its reported force_n, as a probe force track), at the point where the instrument's tip first touched: the organ
deforms about the same, so the difference of the frame times is what the instruments' sweeps, tool contact rows
and posing cost. The two are run alternately, `lumen bench SCENE --json` each (render on, nothing written), and
the CSV gives per scene and per run both totals and the stage medians, then the median over the runs of the
difference of the medians (overhead_median_ms).
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

STAGES = ["physics", "collision", "response", "render", "total"]


def bench(lumen, scene):
    out = subprocess.run([lumen, "bench", scene, "--json"], check=True, capture_output=True, text=True).stdout
    return json.loads(out)


def twin_scene(lumen, scene_path, work):
    """The scene without instruments, with one force probe per instrument replaying its force on the organ."""
    with open(scene_path, encoding="utf-8") as f:
        scene = json.load(f)
    run_dir = os.path.join(work, "first")
    subprocess.run([lumen, "run", scene_path, "--no-render", "--out", run_dir], check=True, capture_output=True)
    with open(os.path.join(run_dir, "report.json"), encoding="utf-8") as f:
        frames = json.load(f)["per_frame"]
    probes = []
    for k, tool in enumerate(scene["instruments"]):
        # Where its tip first touched (the rest wall, within a frame's motion): the probe's point, snapped to the wall.
        touch = next(fr for fr in frames if fr["instruments"][k]["contacts"] > 0)["instruments"][k]
        track = [{"t": 0.0, "force": [0.0, 0.0, 0.0]}]
        for fr in frames:
            track.append({"t": fr["t"], "force": [-c for c in fr["instruments"][k]["force_n"]]})
        probes.append({"name": f"{tool.get('name', 'instrument')}-twin", "point": touch["position"], "track": track})
    twin = dict(scene)
    twin.pop("instruments")
    twin["name"] = scene["name"] + "-twin"
    twin["probes"] = scene.get("probes", []) + probes
    path = os.path.join(work, os.path.basename(scene_path).replace(".json", "-twin.json"))
    with open(path, "w", encoding="utf-8") as f:
        json.dump(twin, f)
    return path


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scenes", nargs="+")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--out", default="docs/bench_instrument_overhead.csv")
    ap.add_argument("--lumen", default="build/lumen")
    a = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as work:
        for scene in a.scenes:
            twin = twin_scene(a.lumen, scene, work)
            diffs = []
            for run in range(a.runs):
                with_tools, without = bench(a.lumen, scene), bench(a.lumen, twin)
                row = {"scene": with_tools["scene"], "run": run + 1, "frames": with_tools["frames"],
                       "render": with_tools["render"]["enabled"],
                       "over_budget_with": with_tools["over_budget_frames"],
                       "over_budget_twin": without["over_budget_frames"]}
                for s in STAGES:
                    row[f"{s}_median_ms_with"] = round(with_tools["stages"][s]["median_ms"], 4)
                    row[f"{s}_median_ms_twin"] = round(without["stages"][s]["median_ms"], 4)
                row["total_p99_ms_with"] = round(with_tools["stages"]["total"]["p99_ms"], 4)
                row["total_p99_ms_twin"] = round(without["stages"]["total"]["p99_ms"], 4)
                row["overhead_median_ms"] = round(row["total_median_ms_with"] - row["total_median_ms_twin"], 4)
                diffs.append(row["overhead_median_ms"])
                rows.append(row)
            print(f"{scene}: instrument overhead on the median frame {statistics.median(diffs):.3f} ms "
                  f"(median of {a.runs} side-by-side runs: {diffs})", file=sys.stderr)
            for row in rows[-a.runs:]:
                row["overhead_median_ms_over_runs"] = round(statistics.median(diffs), 4)
    write_csv(a.out, [f"made by: tools/bench_instrument_overhead.py --runs {a.runs} {' '.join(a.scenes)}",
                      f"machine: {platform.machine()}, {os.cpu_count()} cores; twin = the scene with its instruments "
                      "replaced by force probes replaying their force on the organ"], rows)


if __name__ == "__main__":
    main()
