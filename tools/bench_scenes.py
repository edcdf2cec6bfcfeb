#!/usr/bin/env python3
"""Scenes side by side on one lumen binary: `lumen run <scene> --check --out DIR` (with --no-render unless --render),
the scenes' runs alternating (A B B A A B ...), so that drifts of the machine hit all alike. Per run: physics +
collision + response per frame (pcr) median and p99, the whole frame's median and p99, frames over budget, fallback
frames, frames with intersecting inner-wall pairs (the exact check), the contact force at the end, the equilibrium
residual's median over contact frames, the line-search halvings summed, and, with --tip PREFIX, the tip: the mean
over the probes whose names start with PREFIX of their y displacement at the end, in mm (the reference's measure of
a tip made of several probe points). Written as CSV (--out), one row per run and one of medians per scene, with the
command in its header.

Example (the shipped 8x pinch on the solved coupling against its correcting one, docs/bench_shipped_8x_pinch.csv):
  tools/bench_scenes.py --binary build/lumen --render --runs 3 --tip top --out docs/bench_shipped_8x_pinch.csv \\
      scenes/pinch-tips-corotational-8x.json docs/experiments/pinch-8x-correct.json
"""
import argparse
import json
import os
import statistics
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_ab import frame_statistics, run_session  # noqa: E402
from csv_out import write_csv  # noqa: E402


def tip_indices(scene, prefix):
    """Indices of the scene's probes whose names start with prefix (none: exit with the scene and prefix named)."""
    with open(scene) as f:
        probes = json.load(f).get("probes", [])
    found = [i for i, p in enumerate(probes) if str(p.get("name", "")).startswith(prefix)]
    if not found:
        sys.exit(f"bench_scenes.py: {scene}: no probe whose name starts with {prefix!r} (--tip)")
    return found


def one_run(binary, scene, render, tip):
    """One session with the exact check; its statistics from report.json."""
    report = run_session(binary, scene, render, ["--check"], "bench_scenes.py")
    times = frame_statistics(report)
    frames = report["per_frame"]
    residuals = [f["equilibrium_residual"] for f in frames
                 if f["contacts"] > 0 and f.get("equilibrium_residual") is not None]
    row = {key: times[key] for key in ("pcr_median_ms", "pcr_p99_ms", "total_median_ms", "total_p99_ms",
                                       "over_budget_frames", "fallback_frames")}
    row.update({"intersecting_frames": report["frames_with_intersections"],
                "contact_force_end_n": frames[-1]["contact_force_n"],
                "equilibrium_residual_median": statistics.median(residuals) if residuals else 0.0,
                "halvings": sum(f.get("equilibrium_backtracks") or 0 for f in frames)})
    if tip is not None:
        row["tip_mm"] = 1000.0 * statistics.mean(frames[-1]["probe_displacement_m"][i][1] for i in tip)
    return row


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--binary", required=True, help="the lumen binary")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--render", action="store_true", help="render the frames (as the scene says)")
    ap.add_argument("--tip", help="name prefix of the probes whose mean y displacement is the tip")
    ap.add_argument("--note", default="", help="a line for the CSV header")
    ap.add_argument("--out", required=True)
    ap.add_argument("scenes", nargs="+")
    a = ap.parse_args()
    if a.runs < 1:
        sys.exit(f"bench_scenes.py: --runs must be at least 1, got {a.runs}")
    for path in [a.binary] + a.scenes:
        if not os.path.exists(path):
            sys.exit(f"bench_scenes.py: {path}: no such file")
    tips = {s: tip_indices(s, a.tip) if a.tip else None for s in a.scenes}
    runs = {s: [] for s in a.scenes}
    for k in range(a.runs):
        for scene in (a.scenes if k % 2 == 0 else a.scenes[::-1]):
            runs[scene].append(one_run(a.binary, scene, a.render, tips[scene]))
            print(os.path.basename(scene), runs[scene][-1], flush=True)
    rows = []
    for scene in a.scenes:
        for k, r in enumerate(runs[scene]):
            rows.append({"scene": os.path.basename(scene), "run": k + 1, **{key: round(v, 5) for key, v in r.items()}})
        rows.append({"scene": os.path.basename(scene), "run": "median",
                     **{key: round(statistics.median(r[key] for r in runs[scene]), 5) for key in runs[scene][0]}})
    header = [f"made by: tools/bench_scenes.py {' '.join(sys.argv[1:])}",
              "pcr = physics + collision + response per frame; tip_mm = mean y displacement of the --tip probes at "
              "the end"]
    if a.note:
        header.append(a.note)
    write_csv(a.out, header, rows)


if __name__ == "__main__":
    main()
