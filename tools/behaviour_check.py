#!/usr/bin/env python3
"""Behaviour check: run every shipped scene headless and compare its non-timing outputs with a baseline.

  tools/behaviour_check.py capture DIR [--lumen build/lumen]   # run every scene, keep its outputs in DIR
  tools/behaviour_check.py compare BASE NEW                    # compare two captures; exit 1 on a difference

A capture holds, per scene, report.json (per-frame contacts, response rounds, fallbacks, inverted elements,
numerical failures, physics iterations, reactions, contact force, ...) and positions.csv (the final node
positions, 17 digits). compare prints one line per scene: the largest final-position difference (metres),
the largest per-frame float difference (reactions, contact force, energies) and every count that differs.
Positions must agree within --position-tol (1e-9 m), floats within --float-tol relative (1e-9), counts exactly.
With --repeat BASE2 (a second capture of the same baseline binary), a scene whose two baseline runs differ from
each other is reported as nondeterministic, with both differences, instead of failing: its result depends on
timing (the corotational solve's background factorisation finishes at a different iteration from run to run).
"""
import argparse
import csv
import glob
import json
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# Per-frame fields compared exactly (counts and flags) and within a relative tolerance (floats).
COUNT_FIELDS = ["contacts", "response_iterations", "fallback", "inverted_elements", "numerical_failure",
                "bad_input", "physics_iterations", "physics_converged", "bv_overlaps", "feature_tests"]
FLOAT_FIELDS = ["twist_degrees", "contact_force_n", "kinetic_energy_j", "max_displacement_m"]
TOTAL_FIELDS = ["fallback_frames", "frames_with_inverted_elements", "numerical_failures", "frames"]


def scenes():
    files = sorted(glob.glob(os.path.join(ROOT, "scenes", "*.json")))
    files += sorted(glob.glob(os.path.join(ROOT, "scenes", "hard", "*.json")))
    return files


def scene_key(path):
    rel = os.path.relpath(path, os.path.join(ROOT, "scenes"))
    return rel[:-len(".json")].replace(os.sep, "__")


def capture(out, lumen):
    os.makedirs(out, exist_ok=True)
    for path in scenes():
        key = scene_key(path)
        d = os.path.join(out, key)
        os.makedirs(d, exist_ok=True)
        cmd = [lumen, "run", path, "--no-render", "--out", d, "--positions", os.path.join(d, "positions.csv")]
        r = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        status = "ok" if r.returncode == 0 else f"exit {r.returncode}: {r.stderr.strip()}"
        print(f"{key}: {status}", flush=True)
        if r.returncode != 0:
            return 1
    return 0


def read_positions(path):
    with open(path) as f:
        return [[float(v) for v in row] for row in csv.reader(f)]


def rel_diff(a, b):
    return abs(a - b) / max(1.0, abs(a), abs(b))


def compare_scene(base, new, position_tol, float_tol):
    problems = []
    pa, pb = read_positions(os.path.join(base, "positions.csv")), read_positions(os.path.join(new, "positions.csv"))
    if len(pa) != len(pb):
        return float("inf"), float("inf"), [f"node count {len(pa)} -> {len(pb)}"]
    dpos = max((max(abs(x - y) for x, y in zip(ra, rb)) for ra, rb in zip(pa, pb)), default=0.0)
    if dpos > position_tol:
        problems.append(f"positions differ by {dpos:.3g} m")
    ra, rb = json.load(open(os.path.join(base, "report.json"))), json.load(open(os.path.join(new, "report.json")))
    for k in TOTAL_FIELDS:
        if ra.get(k) != rb.get(k):
            problems.append(f"{k}: {ra.get(k)} -> {rb.get(k)}")
    dfloat = 0.0
    for fa, fb in zip(ra["per_frame"], rb["per_frame"]):
        for k in COUNT_FIELDS:
            if fa.get(k) != fb.get(k):
                problems.append(f"frame {fa['frame']} {k}: {fa.get(k)} -> {fb.get(k)}")
        for k in FLOAT_FIELDS:
            dfloat = max(dfloat, rel_diff(fa.get(k, 0.0), fb.get(k, 0.0)))
        for va, vb in zip(fa["reaction_force_n"], fb["reaction_force_n"]):
            dfloat = max(dfloat, max(rel_diff(x, y) for x, y in zip(va, vb)))
    if dfloat > float_tol:
        problems.append(f"per-frame floats differ by {dfloat:.3g} (relative)")
    return dpos, dfloat, problems


def compare(base, new, position_tol, float_tol, repeat=None):
    failed = 0
    nondeterministic = 0
    keys = sorted(k for k in os.listdir(base) if os.path.isdir(os.path.join(base, k)))
    for key in keys:
        if not os.path.isdir(os.path.join(new, key)):
            print(f"{key}: missing in {new}")
            failed += 1
            continue
        dpos, dfloat, problems = compare_scene(os.path.join(base, key), os.path.join(new, key), position_tol, float_tol)
        if problems and repeat and os.path.isdir(os.path.join(repeat, key)):
            rpos, rfloat, rproblems = compare_scene(os.path.join(base, key), os.path.join(repeat, key), position_tol,
                                                    float_tol)
            if rproblems:
                print(f"{key}: nondeterministic  baseline vs new: position {dpos:.3g} m, float {dfloat:.3g}; "
                      f"baseline vs itself: position {rpos:.3g} m, float {rfloat:.3g}")
                nondeterministic += 1
                continue
        verdict = "same" if not problems else "DIFFERENT"
        print(f"{key}: {verdict}  max position diff {dpos:.3g} m, max float diff {dfloat:.3g}")
        for p in problems[:10]:
            print(f"    {p}")
        if len(problems) > 10:
            print(f"    ... {len(problems) - 10} more")
        failed += bool(problems)
    print(f"{len(keys) - failed - nondeterministic} of {len(keys)} scenes the same, {failed} different, "
          f"{nondeterministic} nondeterministic in the baseline itself")
    return 1 if failed else 0


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    c = sub.add_parser("capture")
    c.add_argument("out")
    c.add_argument("--lumen", default=os.path.join(ROOT, "build", "lumen"))
    m = sub.add_parser("compare")
    m.add_argument("base")
    m.add_argument("new")
    m.add_argument("--position-tol", type=float, default=1e-9)
    m.add_argument("--float-tol", type=float, default=1e-9)
    m.add_argument("--repeat", help="a second capture of the baseline, to tell nondeterministic scenes")
    a = ap.parse_args()
    if a.cmd == "capture":
        return capture(a.out, a.lumen)
    return compare(a.base, a.new, a.position_tol, a.float_tol, a.repeat)


if __name__ == "__main__":
    sys.exit(main())
