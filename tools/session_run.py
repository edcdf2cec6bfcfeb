"""Running one scene headless through `lumen run` for a benchmark: the scene dict written to a temporary folder,
run with the exact intersection check, its report.json returned."""
import json
import math
import os
import subprocess


def run_report(lumen, scene, tmp):
    path = os.path.join(tmp, scene["name"] + ".json")
    with open(path, "w") as f:
        json.dump(scene, f)
    out = os.path.join(tmp, scene["name"])
    subprocess.run([lumen, "run", path, "--no-render", "--check", "--out", out], check=True, capture_output=True)
    with open(os.path.join(out, "report.json")) as f:
        return json.load(f)


def percentile(values, q):
    """Linear-interpolation percentile of a list (as report.json's stage statistics)."""
    v = sorted(values)
    x = q / 100.0 * (len(v) - 1)
    i = int(math.floor(x))
    return v[i] if i + 1 >= len(v) else v[i] + (x - i) * (v[i + 1] - v[i])
