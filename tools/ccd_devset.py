#!/usr/bin/env python3
"""CCD dev-set results: runs `lumen ccd FILE --json` R times per file and writes the median of each number.

usage: tools/ccd_devset.py [--runs 5] [--out docs/ccd_devset.csv] [--lumen build/lumen] [FILE.csv ...]
(default files: tests/data/ccd/handcrafted.csv and simulation.csv)
"""
import argparse
import json
import os
import statistics
import subprocess

HERE = os.path.dirname(os.path.abspath(__file__))
DATA = os.path.normpath(os.path.join(HERE, "..", "tests", "data", "ccd"))
FIELDS = ["queries", "positives", "false_negatives", "false_positives", "mean_ns", "max_ns"]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("files", nargs="*", default=[os.path.join(DATA, "handcrafted.csv"), os.path.join(DATA, "simulation.csv")])
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--out", default="docs/ccd_devset.csv")
    ap.add_argument("--lumen", default="build/lumen")
    a = ap.parse_args()
    lines = []
    for path in a.files:
        runs = [json.loads(subprocess.run([a.lumen, "ccd", path, "--json"], check=True, capture_output=True,
                                          text=True).stdout) for _ in range(a.runs)]
        for kind in ("vf", "ee"):
            vals = [statistics.median(r[kind][f] for r in runs) for f in FIELDS]
            # Counts must not vary between runs (the method is deterministic); times are medians.
            for f in FIELDS[:4]:
                assert len({r[kind][f] for r in runs}) == 1, (path, kind, f)
            lines.append([os.path.basename(path), kind] + [round(v, 1) if isinstance(v, float) else v for v in vals])
            print(f"{os.path.basename(path)} {kind}: " + ", ".join(f"{f} {v}" for f, v in zip(FIELDS, lines[-1][2:])))
    tmp = a.out + ".tmp"
    with open(tmp, "w") as f:
        f.write(f"# made by: tools/ccd_devset.py --runs {a.runs} (each run: build/lumen ccd FILE --json); "
                f"median of {a.runs} runs per number, gap 0\n")
        f.write("file,kind," + ",".join(FIELDS) + "\n")
        for l in lines:
            f.write(",".join(str(v) for v in l) + "\n")
    os.replace(tmp, a.out)


if __name__ == "__main__":
    main()
