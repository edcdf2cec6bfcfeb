#!/usr/bin/env python3
"""Two lumen binaries side by side on scene files: `lumen run <scene> --no-render --out DIR` (or rendered with
--render), runs alternating between the binaries, in the order old new new old old new ... (ABBA), so that drifts
of the machine and a first run's cold caches hit both alike. Per binary and
scene, the median over runs of each run's physics median and p99, of physics + collision + response per frame
(pcr) median and p99, of the whole frame's median, p99 and maximum, of the response's maximum, and of the
back-substitutions over the session (the frames' cg_iterations summed). Written as CSV (--out) with the command in its header.

Example (the supernodal solves, docs/bench_supernodal_solves.csv):
  tools/bench_ab.py --old /tmp/old/lumen --new build/lumen --old-label simplicial --new-label supernodal \\
      --runs 3 --out docs/bench_supernodal_solves.csv scenes/paper-press-corotational-large.json
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from csv_out import write_csv  # noqa: E402


def percentile(values, q):
    """Linear interpolation between closest ranks (numpy's default), q in [0, 100]."""
    v = sorted(values)
    if not v:
        return 0.0
    pos = (len(v) - 1) * q / 100.0
    lo = int(pos)
    hi = min(lo + 1, len(v) - 1)
    return v[lo] + (v[hi] - v[lo]) * (pos - lo)


def run_session(binary, scene, render, extra=(), tool="bench_ab.py"):
    """One session, `lumen run <scene> --out DIR` (with --no-render unless render, and the extra arguments); its
    report.json (a failed run exits with the command and its stderr)."""
    with tempfile.TemporaryDirectory() as out:
        cmd = [binary, "run", scene, "--out", out] + list(extra) + ([] if render else ["--no-render"])
        done = subprocess.run(cmd, capture_output=True, text=True)
        if done.returncode != 0:
            sys.exit(f"{tool}: {' '.join(cmd)} exited {done.returncode}:\n{done.stderr}")
        with open(os.path.join(out, "report.json")) as f:
            return json.load(f)


def frame_statistics(report):
    """A session's frame-time statistics from its report."""
    frames = report["per_frame"]
    pcr = [f["physics_ms"] + f["collision_ms"] + f["response_ms"] for f in frames]
    total = [f["total_ms"] for f in frames]
    physics = report["stages"]["physics"]
    return {"physics_median_ms": physics["median_ms"], "physics_p99_ms": physics["p99_ms"],
            "pcr_median_ms": statistics.median(pcr), "pcr_p99_ms": percentile(pcr, 99),
            "total_median_ms": statistics.median(total), "total_p99_ms": percentile(total, 99),
            "total_max_ms": max(total), "response_max_ms": max(f["response_ms"] for f in frames),
            "back_substitutions": sum(f["cg_iterations"] for f in frames),
            "fallback_frames": report["fallback_frames"], "over_budget_frames": report["over_budget_frames"]}


def one_run(binary, scene, render):
    """One session; its per-run statistics."""
    return frame_statistics(run_session(binary, scene, render))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--old", required=True, help="the old lumen binary")
    ap.add_argument("--new", required=True, help="the new lumen binary")
    ap.add_argument("--old-label", default="old")
    ap.add_argument("--new-label", default="new")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--render", action="store_true", help="render the frames (640x480 unless the scene says)")
    ap.add_argument("--note", default="", help="a line for the CSV header (what old and new are)")
    ap.add_argument("--out", required=True)
    ap.add_argument("scenes", nargs="+")
    a = ap.parse_args()
    if a.runs < 1:
        sys.exit(f"bench_ab.py: --runs must be at least 1, got {a.runs}")
    if a.old_label == a.new_label:
        sys.exit(f"bench_ab.py: --old-label and --new-label must differ, both are {a.old_label!r}")
    if len({os.path.basename(s) for s in a.scenes}) != len(a.scenes):
        sys.exit("bench_ab.py: two scenes have the same file name (the CSV names scenes by file name)")
    for path in [a.old, a.new] + a.scenes:
        if not os.path.exists(path):
            sys.exit(f"bench_ab.py: {path}: no such file")
    variants = [(a.old_label, a.old), (a.new_label, a.new)]
    rows = []
    for scene in a.scenes:
        runs = {label: [] for label, _ in variants}
        for k in range(a.runs):
            for label, binary in (variants if k % 2 == 0 else variants[::-1]):
                runs[label].append(one_run(binary, scene, a.render))
        for label, _ in variants:
            row = {"scene": os.path.basename(scene), "binary": label, "runs": a.runs}
            for key in runs[label][0]:
                row[key] = round(statistics.median(r[key] for r in runs[label]), 4)
            rows.append(row)
            print(row, flush=True)
    header = [f"made by: tools/bench_ab.py {' '.join(sys.argv[1:])}",
              "statistic = median over runs of each run's statistic; pcr = physics + collision + response per frame; "
              "back_substitutions = the frames' cg_iterations summed over the session"]
    if a.note:
        header.append(a.note)
    write_csv(a.out, header, rows)


if __name__ == "__main__":
    main()
