#!/usr/bin/env python3
"""tools/plot_session.py on a real session's report and on malformed reports.

Usage: check_plot_session.py LUMEN PLOT_SESSION SCENE.json WORKDIR

Runs the instrument scene for a few frames (no render), plots its report, and checks: exit 0, both PNGs written
at the documented size, the stage colours present in the stacked plot and the instrument's line colour in the
force plot; then three malformed reports: exit 2, a message naming the missing or bad field, nothing written.
Exit 0 when all hold, 1 otherwise."""
import json
import os
import shutil
import subprocess
import sys

try:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.image as mpimg
    import numpy as np
except ImportError as e:
    sys.exit(f"check_plot_session: FAIL: python3-matplotlib is missing ({e}); tools/setup.sh installs it")

FRAMES = 12
EXPECTED_SIZE = (495, 880)  # rows, columns: plot_session's FIGSIZE (8 x 4.5 in) at 110 dpi
PHYSICS_RGB = (0x1F, 0x77, 0xB4)  # plot_session's physics colour, also matplotlib's C0 (first instrument)
RENDER_RGB = (0x2C, 0xA0, 0x2C)
COLOUR_TOL = 3  # of 255, antialiasing leaves the bar interiors exact


def fail(msg):
    sys.exit(f"check_plot_session: FAIL: {msg}")


def has_colour(png, rgb):
    img = (mpimg.imread(png)[:, :, :3] * 255.0).round().astype(int)
    return bool((np.abs(img - np.array(rgb)).max(axis=2) <= COLOUR_TOL).any())


def main(lumen, plot, scene, work):
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    run_dir = os.path.join(work, "run")
    r = subprocess.run([lumen, "run", scene, "--frames", str(FRAMES), "--no-render", "--out", run_dir],
                       capture_output=True, text=True)
    if r.returncode != 0:
        fail(f"lumen run exited {r.returncode}: {r.stderr}")
    report = os.path.join(run_dir, "report.json")
    r = subprocess.run([sys.executable, plot, report, "--out-dir", os.path.join(work, "png")],
                       capture_output=True, text=True)
    if r.returncode != 0:
        fail(f"plot_session exited {r.returncode}: {r.stderr}")
    reaction = os.path.join(work, "png", "session_reaction.png")
    stages = os.path.join(work, "png", "session_stages.png")
    for png in (reaction, stages):
        if not os.path.isfile(png):
            fail(f"{png} not written")
        shape = mpimg.imread(png).shape[:2]
        if shape != EXPECTED_SIZE:
            fail(f"{png}: {shape[0]}x{shape[1]} pixels, expected {EXPECTED_SIZE[0]}x{EXPECTED_SIZE[1]}")
    if not has_colour(stages, PHYSICS_RGB):
        fail("stage plot holds no physics bar")
    if has_colour(stages, RENDER_RGB):
        fail("stage plot draws render bars for a --no-render session (render_ms should be 0)")
    if not has_colour(reaction, PHYSICS_RGB):
        fail("force plot holds no line for the first instrument")

    # Malformed reports: (mutation, text the message must hold).
    with open(report, encoding="utf-8") as f:
        good = json.load(f)
    cases = [
        (lambda j: j.pop("per_frame"), "missing field 'per_frame'"),
        (lambda j: j["per_frame"][3].pop("physics_ms"), "per_frame[3]: missing field 'physics_ms'"),
        (lambda j: j["per_frame"][2]["instruments"][0].__setitem__("force_n", [1.0, 2.0]),
         "per_frame[2].instruments[0].force_n: expected a 3-vector"),
    ]
    for k, (mutate, text) in enumerate(cases):
        bad = json.loads(json.dumps(good))
        mutate(bad)
        path = os.path.join(work, f"bad{k}.json")
        with open(path, "w", encoding="utf-8") as f:
            json.dump(bad, f)
        out = os.path.join(work, f"bad{k}")
        r = subprocess.run([sys.executable, plot, path, "--out-dir", out], capture_output=True, text=True)
        if r.returncode != 2:
            fail(f"malformed report {k}: exit {r.returncode}, expected 2")
        if text not in r.stderr or path not in r.stderr:
            fail(f"malformed report {k}: message {r.stderr.strip()!r} does not name {path} and {text!r}")
        if os.path.isdir(out) and os.listdir(out):
            fail(f"malformed report {k}: wrote {os.listdir(out)}")
    print("check_plot_session: OK")


if __name__ == "__main__":
    if len(sys.argv) != 5:
        sys.exit(__doc__)
    main(*sys.argv[1:])
