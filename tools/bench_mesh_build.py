#!/usr/bin/env python3
"""Mesh build time at load (issue 11: "building the mesh, centreline or surface to tets, takes at most 2 s for
50,000 tets, reported in report.json"): shipped organ scenes with their resolution raised past 50,000 tets, each
run R times as `lumen run SCENE --no-render --frames 1`; the CSV gives report.json's mesh.build_ms (median over the
runs, and every run), the tets and the worst dihedral angle.

usage: tools/bench_mesh_build.py [--runs 3] [--out docs/bench_mesh_build.csv] [--lumen build/lumen]
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

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# An override naming the full aneurysm's outer surface grown 0.5 mm by lumen_grow_surface into the run's folder
# (a surface pair of about 42,600 tets: the largest real pair at hand).
GROWN_OUTER = "<grown outer>"
# ... and the inner surface it wrote beside it (the original with the one vertex it moved to untangle a fold-over).
GROWN_INNER = "<grown inner>"
# (case, shipped scene, overrides of its "mesh" object; file overrides relative to the repository): each past
# 50,000 tets, or the largest surface pair.
CASES = [
    ("whole colon swept: 16 around and 2 mm rings", "scenes/colon-whole-press.json",
     {"segments_around": 16, "segment_length": 2.0}),
    ("whole colon swept: 24 around and 2 mm rings", "scenes/colon-whole-press.json",
     {"segments_around": 24, "segment_length": 2.0}),
    ("full aneurysm wall grown 0.5 mm in 2 layers", "scenes/aneurysm-wall-press.json", {"layers": 2}),
    ("full aneurysm wall grown 0.5 mm in 3 layers", "scenes/aneurysm-wall-press.json", {"layers": 3}),
    ("full aneurysm surface pair: both surfaces as lumen_grow_surface wrote them, mesher auto",
     "scenes/aneurysm-pair-press.json", {"inner": GROWN_INNER, "outer": GROWN_OUTER}),
    ("full aneurysm surface pair: both surfaces as lumen_grow_surface wrote them, Netgen",
     "scenes/aneurysm-pair-press.json", {"inner": GROWN_INNER, "outer": GROWN_OUTER, "mesher": "netgen"}),
    ("full aneurysm surface pair: the original surface inside the grown one, mesher auto",
     "scenes/aneurysm-pair-press.json", {"inner": "data/organs/sofa-aneurysm3D_1.off", "outer": GROWN_OUTER}),
]

# Keys of "mesh" that name files relative to the scene (made absolute in the copy written elsewhere).
FILE_KEYS = ("centreline", "surface", "inner", "outer", "file")


def grow_outer(lumen, folder):
    grow = os.path.join(os.path.dirname(os.path.abspath(lumen)), "lumen_grow_surface")
    inner, outer = os.path.join(folder, "grown_inner.off"), os.path.join(folder, "grown_outer.off")
    subprocess.run([grow, os.path.join(ROOT, "data/organs/sofa-aneurysm3D_1.off"), "0.5", inner, outer],
                   check=True, stdout=subprocess.DEVNULL)
    return inner, outer


def scene_copy(path, overrides, folder, lumen):
    with open(os.path.join(ROOT, path)) as f:
        scene = json.load(f)
    base = os.path.dirname(os.path.join(ROOT, path))
    mesh = scene["mesh"]
    for key in FILE_KEYS:
        if isinstance(mesh.get(key), str):
            mesh[key] = os.path.normpath(os.path.join(base, mesh[key]))
    for key, value in overrides.items():
        if value in (GROWN_INNER, GROWN_OUTER):
            value = grow_outer(lumen, folder)[0 if value == GROWN_INNER else 1]
        elif key in FILE_KEYS:
            value = os.path.join(ROOT, value)
        mesh[key] = value
    scene["probes"] = []  # (their points sit on the shipped mesh's outer wall; only the build is timed)
    scene.pop("instruments", None)
    out = os.path.join(folder, os.path.basename(path))
    with open(out, "w") as f:
        json.dump(scene, f)
    return out


def run_once(lumen, scene, folder):
    out = os.path.join(folder, "out")
    proc = subprocess.run([lumen, "run", scene, "--no-render", "--frames", "1", "--out", out],
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if proc.returncode != 0:
        sys.exit(f"bench_mesh_build: {scene}: lumen exited {proc.returncode}:\n{proc.stdout}")
    with open(os.path.join(out, "report.json")) as f:
        return json.load(f)["mesh"]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--out", default=os.path.join(ROOT, "docs", "bench_mesh_build.csv"))
    ap.add_argument("--lumen", default=os.path.join(ROOT, "build", "lumen"))
    args = ap.parse_args()
    rows = []
    for case, path, overrides in CASES:
        with tempfile.TemporaryDirectory(prefix="lumen_build_") as folder:
            scene = scene_copy(path, overrides, folder, args.lumen)
            meshes = [run_once(args.lumen, scene, folder) for _ in range(args.runs)]
        times = [m["build_ms"] for m in meshes]
        m = meshes[0]
        rows.append({
            "case": case, "scene": path,
            "overrides": " ".join(f"{k}={v.strip('<>') if v in (GROWN_INNER, GROWN_OUTER) else v}"
                                  for k, v in overrides.items()),
            "mesher": m.get("mesher", ""),
            "source": m["source"], "tets": m["tets"], "nodes": m["nodes"],
            "build_ms_median": round(statistics.median(times), 1),
            "build_ms_runs": " ".join(f"{t:.1f}" for t in times),
            "mesher_ms_median": round(statistics.median(x.get("mesher_ms", 0.0) for x in meshes), 1),
            "min_dihedral_deg": round(m["min_dihedral_deg"]["min"], 2),
        })
        print(f"{case}: {m['tets']} tets, build {statistics.median(times):.1f} ms (runs {rows[-1]['build_ms_runs']})")
    comments = [f"made by: tools/bench_mesh_build.py --runs {args.runs}",
                "build_ms: report.json mesh.build_ms (reading the files and making the tets; for a surface wall the "
                "growth with its exact intersection checks; for a surface pair both files' checks and the mesher, "
                "mesher_ms its own share), median of the runs; lumen run --no-render --frames 1",
                f"machine: {os.uname().machine}, {os.cpu_count()} cores"]
    write_csv(args.out, comments, rows)


if __name__ == "__main__":
    main()
