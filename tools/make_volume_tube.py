#!/usr/bin/env python3
"""Writes data/volume-tube.msh, the tet mesh of scenes/volume-tube-pinch.json: Lumen's own hollow cylinder (the
mesh of scenes/fig5-squeeze.json) as a gmsh MSH 2.2 ASCII file in millimetres, written by meshio, with its walls
as tagged boundary triangles (physical surfaces "inner" 1, "outer" 2, "ends" 3).

The rest mesh comes from Lumen itself: fig5-squeeze with its probe unloaded, run for one frame with
--export-volume (zero load: the exported positions are the rest positions). The boundary triangles are the tet
faces used once, oriented out of the volume; a triangle is on the inner or outer wall when its three nodes are at
the scene's inner or outer radius from the axis, else on an end cap.

Usage (Debian's python3-meshio): /usr/bin/python3 tools/make_volume_tube.py build/lumen
"""
import json
import os
import subprocess
import sys
import tempfile

import meshio
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MM_PER_M = 1000.0
TAGS = {"inner": 1, "outer": 2, "ends": 3}
VOLUME_TAG = 4
RADIUS_TOLERANCE = 1e-9  # metres


def rest_mesh(lumen, scene):
    """Nodes (metres) and tets of the scene's mesh, from lumen run --export-volume with the probe unloaded."""
    for probe in scene["probes"]:
        for key in probe["track"]:
            key["force"] = [0.0, 0.0, 0.0]
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "rest.json")
        with open(path, "w") as f:
            json.dump(scene, f)
        subprocess.run([lumen, "run", path, "--out", tmp, "--frames", "1", "--no-render", "--export-volume"],
                       check=True, stdout=subprocess.DEVNULL)
        m = meshio.read(os.path.join(tmp, "volume", "volume_000001.vtu"))
    return m.points, m.cells_dict["tetra"]


def boundary(tets, points):
    """Tet faces used once, oriented out of the volume (the tet's fourth node behind them)."""
    faces = {}
    for t in tets:
        for a, b, c, d in ((0, 1, 2, 3), (0, 1, 3, 2), (0, 2, 3, 1), (1, 2, 3, 0)):
            key = tuple(sorted((t[a], t[b], t[c])))
            f = [t[a], t[b], t[c]]
            n = np.cross(points[f[1]] - points[f[0]], points[f[2]] - points[f[0]])
            if np.dot(n, points[t[d]] - points[f[0]]) > 0:
                f = [f[0], f[2], f[1]]
            faces.setdefault(key, []).append(f)
    return np.array([v[0] for v in faces.values() if len(v) == 1])


def main():
    lumen = sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "build", "lumen")
    with open(os.path.join(ROOT, "scenes", "fig5-squeeze.json")) as f:
        scene = json.load(f)
    points, tets = rest_mesh(lumen, scene)
    tris = boundary(tets, points)
    radius = np.hypot(points[:, 0], points[:, 1])
    tags = np.full(len(tris), TAGS["ends"])
    for name in ("inner", "outer"):
        on_wall = np.abs(radius - scene["mesh"][name + "_radius"]) < RADIUS_TOLERANCE
        tags[on_wall[tris].all(axis=1)] = TAGS[name]
    mesh = meshio.Mesh(
        points * MM_PER_M, [("triangle", tris), ("tetra", tets)],
        cell_data={"gmsh:physical": [tags, np.full(len(tets), VOLUME_TAG)],
                   "gmsh:geometrical": [tags, np.full(len(tets), 1)]},
        field_data={**{name: np.array([tag, 2]) for name, tag in TAGS.items()}, "wall": np.array([VOLUME_TAG, 3])})
    out = os.path.join(ROOT, "data", "volume-tube.msh")
    mesh.write(out, file_format="gmsh22", binary=False)
    print(f"{out}: {len(points)} nodes, {len(tets)} tets, " +
          ", ".join(f"{(tags == tag).sum()} {name} triangles" for name, tag in TAGS.items()))


if __name__ == "__main__":
    main()
