#!/usr/bin/env python3
"""Runs every hard-case scene (scenes/hard/*.json) and prints its frame times and health as a Markdown table.

For each scene:
  - `lumen bench SCENE --json --no-render`: per-stage frame times of the simulation alone;
  - `lumen bench SCENE --json` (unless --no-render): the same with every frame drawn;
  - `lumen run SCENE --no-render --check --out TMP`: per-frame report (inverted elements, contacts, fallbacks,
    numerical failures) and the exact intersection count of the inner wall on every frame.
Timings are measurements of this machine, not pass/fail thresholds (the tests in tests/scenes/test_hard.cpp
assert the behaviour).

With --model corotational (or linear), each scene runs as a copy with material.model set to it (written to a
temporary folder; scenes already on that model run as they are): the hard cases on the other model.
With --settings-from SCENE as well, each quasi-static corotational copy also takes that scene's solver keys (over its
own) and its contact coupling keys (COUPLING_KEYS), e.g. scenes/pinch-tips-corotational-8x.json: the real-time
corotational settings (the solved coupling, the warped tangent, the work bound); dynamic scenes keep their own.

Usage: tools/hard_cases.py [--lumen build/lumen] [--no-render] [--model NAME] [--settings-from SCENE]
                           [--json OUT.json] [SCENE ...]
"""
import argparse
import glob
import json
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
STAGES = ("input", "physics", "collision", "response", "render", "total")
# The collision keys --settings-from copies: how the contacts meet the corotational solve.
COUPLING_KEYS = ("coupling", "equilibrium_steps", "equilibrium_hessian", "prediction_back_substitutions")


def run_json(cmd):
    """Runs a lumen command that prints one JSON object; exits with its message when it fails."""
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit("failed (%d): %s\n%s" % (p.returncode, " ".join(cmd), p.stderr.strip()))
    return json.loads(p.stdout)


def health(lumen, scene):
    """Per-frame maxima and counts from a checked run (no rendering)."""
    with tempfile.TemporaryDirectory(prefix="lumen-hard-") as out:
        p = subprocess.run([lumen, "run", scene, "--no-render", "--check", "--out", out], capture_output=True, text=True)
        if p.returncode != 0:
            sys.exit("failed (%d): lumen run %s\n%s" % (p.returncode, scene, p.stderr.strip()))
        with open(os.path.join(out, "report.json")) as f:
            report = json.load(f)
    frames = report["per_frame"]
    return {
        "frames": report["frames"],
        "inverted_max": max(f["inverted_elements"] for f in frames),
        "contacts_max": max(f["contacts"] for f in frames),
        "fallback_frames": report["fallback_frames"],
        "numerical_failures": report["numerical_failures"],
        "frames_with_intersections": report["frames_with_intersections"],
        "physics_unconverged_frames": sum(1 for f in frames if not f["physics_converged"]),
        "fallback_kept_min": min([f.get("fallback_kept", 1.0) for f in frames if f["fallback"]] or [1.0]),
    }


def with_model(scene, model, folder, settings=None):
    """(path, applied): the scene file as it is when it already uses `model` (and no settings apply), else a copy in
    `folder` with material.model set and, for a quasi-static corotational scene, the settings' solver keys and
    coupling keys (applied: whether they were)."""
    with open(scene) as f:
        data = json.load(f)
    quasi_static = data.get("solver", {}).get("type", "static") != "dynamic"
    apply = settings is not None and model == "corotational" and quasi_static
    if data.get("material", {}).get("model", "linear") == model and not apply:
        return scene, False
    data.setdefault("material", {})["model"] = model
    if apply:
        data.setdefault("solver", {}).update(settings.get("solver", {}))
        collision = data.setdefault("collision", {})
        collision.update({k: v for k, v in settings.get("collision", {}).items() if k in COUPLING_KEYS})
    data["name"] = data.get("name", os.path.splitext(os.path.basename(scene))[0]) + "-" + model
    copy = os.path.join(folder, os.path.basename(scene))
    with open(copy, "w") as f:
        json.dump(data, f, indent=1)
    return copy, apply


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenes", nargs="*", help="scene files (default: scenes/hard/*.json)")
    ap.add_argument("--lumen", default=os.path.join(ROOT, "build", "lumen"), help="the lumen binary")
    ap.add_argument("--no-render", action="store_true", help="skip the runs with rendering")
    ap.add_argument("--json", help="also write all numbers to this JSON file")
    ap.add_argument("--model", choices=["linear", "corotational"], help="run every scene with this material model")
    ap.add_argument("--settings-from", help="with --model corotational: a scene whose solver and coupling keys the "
                    "quasi-static copies take")
    args = ap.parse_args()
    settings = None
    if args.settings_from:
        if args.model != "corotational":
            sys.exit("--settings-from goes with --model corotational")
        try:
            with open(args.settings_from) as f:
                settings = json.load(f)
        except (OSError, ValueError) as e:
            sys.exit("--settings-from: %s: %s" % (args.settings_from, e))
    if not os.access(args.lumen, os.X_OK):
        sys.exit("lumen binary not found or not executable: %s (build it, or pass --lumen)" % args.lumen)
    scenes = args.scenes or sorted(glob.glob(os.path.join(ROOT, "scenes", "hard", "*.json")))
    if not scenes:
        sys.exit("no scenes found")

    # Measure each scene: bench without and with rendering, then a checked run for the health numbers.
    results = []
    copies = tempfile.TemporaryDirectory(prefix="lumen-hard-model-")
    for scene in scenes:
        name = os.path.splitext(os.path.basename(scene))[0]
        if args.model:
            copy, applied = with_model(scene, args.model, copies.name, settings)
            name += "" if copy == scene else " (%s%s)" % (args.model, ", real-time settings" if applied else "")
            scene = copy
        print("running %s ..." % name, file=sys.stderr, flush=True)
        row = {"scene": name, "sim": run_json([args.lumen, "bench", scene, "--json", "--no-render"])["stages"]}
        if not args.no_render:
            row["render"] = run_json([args.lumen, "bench", scene, "--json"])["stages"]
        row.update(health(args.lumen, scene))
        results.append(row)

    # Summary table: worst and median total frame time, simulation alone and with rendering.
    head = ["scene", "frames", "worst ms (sim)", "median ms (sim)"]
    if not args.no_render:
        head += ["worst ms (+render)", "median ms (+render)"]
    head += ["inverted max", "contacts max", "fallback frames", "least motion kept", "intersecting frames", "failures",
             "unconverged"]
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for r in results:
        cells = [r["scene"], str(r["frames"]), "%.2f" % r["sim"]["total"]["max_ms"], "%.2f" % r["sim"]["total"]["median_ms"]]
        if not args.no_render:
            cells += ["%.2f" % r["render"]["total"]["max_ms"], "%.2f" % r["render"]["total"]["median_ms"]]
        cells += [str(r["inverted_max"]), str(r["contacts_max"]), str(r["fallback_frames"]), "%.3f" % r["fallback_kept_min"],
                  str(r["frames_with_intersections"]), str(r["numerical_failures"]), str(r["physics_unconverged_frames"])]
        print("| " + " | ".join(cells) + " |")

    # Worst frame per stage (simulation alone; render from the rendering run).
    print()
    print("| scene | " + " | ".join("worst %s ms" % s for s in STAGES) + " |")
    print("|" + "---|" * (len(STAGES) + 1))
    for r in results:
        cells = []
        for s in STAGES:
            src = r.get("render", r["sim"]) if s == "render" else r["sim"]
            cells.append("%.2f" % src[s]["max_ms"])
        print("| %s | %s |" % (r["scene"], " | ".join(cells)))

    if args.json:
        # Written under a temporary name, then renamed: never a half-written file.
        tmp = args.json + ".tmp"
        with open(tmp, "w") as f:
            json.dump(results, f, indent=1)
        os.replace(tmp, args.json)


if __name__ == "__main__":
    main()
