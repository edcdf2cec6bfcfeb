#!/usr/bin/env python3
"""Old against new lumen binary on the corotational scenes: `lumen bench <scene> --no-render --json`, runs
alternating between the binaries; per binary and scene the median over runs of the physics median and p99
(and max), written as docs/bench_corotational_kernels.csv (or --out)."""
import argparse
import json
import os
import statistics
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from csv_out import write_csv  # noqa: E402


def physics(binary, scene, env=None):
    full_env = dict(os.environ, **(env or {}))
    out = subprocess.run([binary, "bench", scene, "--no-render", "--json"], check=True, capture_output=True,
                         text=True, env=full_env).stdout
    return json.loads(out)["stages"]["physics"]


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--old", required=True)
    ap.add_argument("--new", required=True)
    ap.add_argument("--new-env", action="append", default=[],
                    help="also run the new binary with this environment variable set, VAR=VALUE (repeatable)")
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--out", default="docs/bench_corotational_kernels.csv")
    ap.add_argument("scenes", nargs="+")
    a = ap.parse_args()
    variants = [("old", a.old, {}), ("new", a.new, {})]
    variants += [("new " + e, a.new, dict([e.split("=", 1)])) for e in a.new_env]
    rows = []
    for scene in a.scenes:
        runs = {label: [] for label, _, _ in variants}
        # Alternate the binaries so that drifts of the machine hit all alike.
        for _ in range(a.runs):
            for label, binary, env in variants:
                runs[label].append(physics(binary, scene, env))
        for label, _, _ in variants:
            r = runs[label]
            rows.append({"scene": os.path.basename(scene).removesuffix(".json"), "binary": label, "runs": a.runs,
                         "physics_median_ms": round(statistics.median(x["median_ms"] for x in r), 4),
                         "physics_p99_ms": round(statistics.median(x["p99_ms"] for x in r), 4),
                         "physics_max_ms": round(statistics.median(x["max_ms"] for x in r), 4)})
            print(rows[-1], flush=True)
    cmd = "tools/bench_corotational_kernels.py " + " ".join(sys.argv[1:])
    write_csv(a.out, [f"made by: {cmd}", "machine: x86_64, 2 cores; statistic = median over runs of each per-run "
                      "statistic; old = main c034cd6, new = branch kernels-openmp f223161 (OpenMP)"], rows)


if __name__ == "__main__":
    main()
