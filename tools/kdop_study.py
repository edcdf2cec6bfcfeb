#!/usr/bin/env python3
"""k-DOP study (the paper's claim: 26-DOPs cut bounding-volume false positives to about 40% of AABBs).

For each scene and k in 6, 14, 18, 26: bounding-volume overlaps of the inner-wall BVH over the whole session,
how many of them hold no contact (false positives), the same for pairs of triangles that share no vertex
(neighbours' boxes always overlap, whatever k), and the collision stage's time (median over runs of the
per-run median, rendering off). Writes a CSV and prints a table.

usage: tools/kdop_study.py [--runs 3] [--out docs/kdop_study.csv] [--lumen build/lumen] SCENE.json ...
"""
import argparse
import json
import statistics
import subprocess
import sys

from csv_out import write_csv


def bench(lumen, scene, k, classify):
    cmd = [lumen, "bench", scene, "--json", "--no-render", "--kdop", str(k)] + (["--classify-overlaps"] if classify else [])
    return json.loads(subprocess.run(cmd, check=True, capture_output=True, text=True).stdout)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scenes", nargs="+")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--out", default="docs/kdop_study.csv")
    ap.add_argument("--lumen", default="build/lumen")
    a = ap.parse_args()
    rows = []
    for scene in a.scenes:
        base_fp = None
        for k in (6, 14, 18, 26):
            c = bench(a.lumen, scene, k, True)["overlap_classification"]
            times = [bench(a.lumen, scene, k, False) for _ in range(a.runs)]
            coll = statistics.median(t["stages"]["collision"]["median_ms"] for t in times)
            coll_p99 = statistics.median(t["stages"]["collision"]["p99_ms"] for t in times)
            fp = c["false_positives"]
            sfp = c["separate_false_positives"]
            if k == 6:
                base_fp, base_sfp = fp, sfp
            rows.append({"scene": times[0]["scene"], "k": k, "detect_calls": c["detect_calls"],
                         "bv_overlaps": c["bv_overlaps"], "with_contact": c["with_contact"], "false_positives": fp,
                         "fp_vs_aabb": round(fp / base_fp, 4) if base_fp else "",
                         "separate_bv_overlaps": c["separate_bv_overlaps"], "separate_false_positives": sfp,
                         "separate_fp_vs_aabb": round(sfp / base_sfp, 4) if base_sfp else "",
                         "collision_median_ms": round(coll, 4), "collision_p99_ms": round(coll_p99, 4)})
            print(f"{rows[-1]['scene']:28s} k={k:2d} overlaps {c['bv_overlaps']:9d} false positives {fp:9d} "
                  f"({rows[-1]['fp_vs_aabb']} of AABB); non-neighbour false positives {sfp:8d} "
                  f"({rows[-1]['separate_fp_vs_aabb']} of AABB); collision median {coll:.3f} ms", file=sys.stderr)
    write_csv(a.out, [f"made by: tools/kdop_study.py --runs {a.runs} {' '.join(a.scenes)}"], rows)


if __name__ == "__main__":
    main()
