"""Running one scene headless through `lumen run` for a benchmark: the scene dict written to a temporary folder,
run with the exact intersection check, its report.json returned."""
import json
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
