#!/usr/bin/env python3
"""Haptic-loop benchmark: `lumen serve SCENE` driven by build/lumen_device_sim (a mass-spring hand sending TRANSFORM
at 1 kHz over loopback and feeling the SENSOR reaction) while the simulation runs and writes frames; R runs. Writes
a CSV of the haptic loop's measured rate, period p50/p99/max, overruns and clamps, the TRANSFORM -> SENSOR latency
median (server side: from a pose's arrival to the send of the first SENSOR rendered at it) and the frame-time
median, one row per run.

usage: tools/bench_haptics.py [--runs 3] [--out docs/bench_haptics.csv] [--lumen build/lumen]
                              [--device-sim build/lumen_device_sim] [--port 18950] [SCENE.json]
"""
import argparse
import json
import os
import resource
import platform
import subprocess
import sys
import tempfile
import time

from csv_out import write_csv

# How long to wait for the server to listen (it compiles the model first), and to end, seconds.
LISTEN_TIMEOUT_S = 120.0
END_TIMEOUT_S = 300.0
# The server's address-space limit (a runaway session must not take the machine), bytes.
MEMORY_LIMIT_BYTES = 4 << 30


def limit_memory():
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT_BYTES, MEMORY_LIMIT_BYTES))


def one_run(a, scene, out_dir):
    log_path = os.path.join(out_dir, "serve.log")
    with open(log_path, "w") as log:
        serve = subprocess.Popen([a.lumen, "serve", scene, "--host", "127.0.0.1", "--port", str(a.port),
                                  "--out", out_dir], stdout=log, stderr=subprocess.STDOUT,
                                 preexec_fn=limit_memory)
    t0 = time.time()
    while "serving " not in open(log_path).read():
        if serve.poll() is not None or time.time() - t0 > LISTEN_TIMEOUT_S:
            sys.exit(f"lumen serve did not start: {open(log_path).read()}")
        time.sleep(0.05)
    scene_json = json.load(open(scene))
    seconds = scene_json["frames"] / scene_json["fps"]
    dev = subprocess.run([a.device_sim, "--port", str(a.port), "--seconds", str(seconds), "--depth-mm", "4"],
                         check=True, capture_output=True, text=True)
    try:
        code = serve.wait(timeout=END_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        serve.kill()
        code = serve.wait()
    if code != 0:
        sys.exit(f"lumen serve failed: {open(log_path).read()}")
    r = json.load(open(os.path.join(out_dir, "report.json")))
    h, s = r["haptics"], r["serve"]
    return {"scene": r["scene"], "nodes": r["mesh"]["nodes"], "frames": r["frames"],
            "haptic_rate_hz": round(h["rate_hz"], 2), "haptic_target_hz": h["rate_hz_target"],
            "period_p50_ms": round(h["period_p50_ms"], 4), "period_p99_ms": round(h["period_p99_ms"], 4),
            "period_max_ms": round(h["period_max_ms"], 3), "overruns": h["overruns"], "ticks": h["ticks"],
            "force_clamps": h["force_clamps"], "stiffness_clamps": h["stiffness_clamps"],
            "transform_received": s["received"].get("TRANSFORM", 0), "sensors_sent": s["sensors_sent"],
            "latency_median_ms": round(s["latency_ms"]["median"], 4),
            "frame_total_median_ms": round(r["stages"]["total"]["median_ms"], 3),
            "over_budget_frames": r["over_budget_frames"],
            "max_force_felt_n": json.loads(dev.stdout.strip().splitlines()[-1])["max_force_n"]}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scene", nargs="?", default="scenes/instrument-device-probe.json")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--out", default="docs/bench_haptics.csv")
    ap.add_argument("--lumen", default="build/lumen")
    ap.add_argument("--device-sim", default="build/lumen_device_sim")
    ap.add_argument("--port", type=int, default=18950)
    a = ap.parse_args()
    rows = []
    for i in range(a.runs):
        with tempfile.TemporaryDirectory() as d:
            row = one_run(a, a.scene, d)
        row = {"run": i + 1, **row}
        rows.append(row)
        print(f"run {i + 1}: {row['haptic_rate_hz']} Hz, period p99 {row['period_p99_ms']} ms, "
              f"latency median {row['latency_median_ms']} ms, frame median {row['frame_total_median_ms']} ms",
              file=sys.stderr)
    write_csv(a.out, [f"made by: tools/bench_haptics.py --runs {a.runs} {a.scene}",
                      f"machine: {platform.machine()}, {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} "
                      f"at the end (shared with other builds); lumen serve writes PNG frames while the haptic loop runs"],
              rows)


if __name__ == "__main__":
    main()
