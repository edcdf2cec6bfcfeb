#!/usr/bin/env python3
"""lumen run --export-volume, read back with an independent reader (meshio) and checked against independent truths.

Usage: check_volume_export.py LUMEN SCENE.json WORKDIR

Runs the scene (no render) with --export-volume and --positions, then checks every frame's .vtu and the .pvd:
node and tet counts, the rest mesh (points minus displacement) against the hollow-cylinder node formula of the
README, the last frame's points against the --positions CSV, von Mises per tet recomputed here from the
exported displacements and the scene's material, and the contact flags (only inner-wall nodes, present on the
frames the report says have contacts). Exit 0 when all hold, 1 otherwise (also when meshio is missing)."""
import json
import math
import os
import subprocess
import sys
import xml.etree.ElementTree as ET

try:
    import meshio
    import numpy as np
except ImportError as e:
    sys.exit(f"check_volume_export: FAIL: python3-meshio is missing ({e}); install it with "
             f"'apt-get install python3-meshio' (tools/setup.sh does) for {sys.executable}")

# Tolerances: exported reals carry 17 significant digits, so positions round-trip; von Mises is recomputed in a
# different order of operations.
POSITION_TOL_M = 1e-15
VON_MISES_REL_TOL = 1e-9
VTK_TETRA = 10


def fail(msg):
    sys.exit(f"check_volume_export: FAIL: {msg}")


def rest_nodes(mesh):
    """The hollow cylinder's nodes by the README's formula: id (j (layers + 1) + k) around + i."""
    around, along, layers = mesh["segments_around"], mesh["segments_along"], mesh["layers"]
    ri, ro, length = mesh["inner_radius"], mesh["outer_radius"], mesh["length"]
    x = np.zeros((around * (along + 1) * (layers + 1), 3))
    for j in range(along + 1):
        for k in range(layers + 1):
            r = ri + (ro - ri) * k / layers
            for i in range(around):
                th = 2.0 * math.pi * i / around
                x[(j * (layers + 1) + k) * around + i] = (r * math.cos(th), r * math.sin(th), length * j / along)
    return x


def von_mises(rest, u, tets, young, nu):
    """Per tet: H = dU dX^-1, eps = sym H, sigma = lambda tr(eps) I + 2 mu eps, sqrt(3/2 s:s)."""
    lam = young * nu / ((1 + nu) * (1 - 2 * nu))
    mu = young / (2 * (1 + nu))
    out = np.zeros(len(tets))
    for t, c in enumerate(tets):
        dx = (rest[c[1:]] - rest[c[0]]).T
        du = (u[c[1:]] - u[c[0]]).T
        h = du @ np.linalg.inv(dx)
        eps = 0.5 * (h + h.T)
        sigma = lam * np.trace(eps) * np.eye(3) + 2 * mu * eps
        s = sigma - np.trace(sigma) / 3 * np.eye(3)
        out[t] = math.sqrt(1.5 * np.sum(s * s))
    return out


def main():
    lumen, scene_path, work = sys.argv[1:4]
    scene = json.load(open(scene_path))
    positions = os.path.join(work, "final.csv")
    run = subprocess.run([lumen, "run", scene_path, "--out", work, "--no-render", "--export-volume",
                          "--positions", positions], capture_output=True, text=True)
    if run.returncode != 0:
        fail(f"lumen run exited {run.returncode}: {run.stderr}")
    if "mesh: " not in run.stdout or "min dihedral angle" not in run.stdout:
        fail(f"no mesh-quality line at run start:\n{run.stdout}")
    # The option belongs to run only: bench refuses it, exit 2, naming it.
    bad = subprocess.run([lumen, "bench", scene_path, "--export-volume"], capture_output=True, text=True)
    if bad.returncode != 2 or "--export-volume" not in bad.stderr:
        fail(f"lumen bench --export-volume: exit {bad.returncode}, stderr {bad.stderr!r}")
    report = json.load(open(os.path.join(work, "report.json")))
    frames = report["per_frame"]

    # The collection: one dataset per frame, in order, at the frame's time; no temporary left behind.
    pvd = ET.parse(os.path.join(work, "volume.pvd")).getroot()
    sets = pvd.find("Collection").findall("DataSet")
    if len(sets) != len(frames):
        fail(f"volume.pvd lists {len(sets)} datasets, the report {len(frames)} frames")
    leftovers = [f for f in os.listdir(os.path.join(work, "volume")) if ".tmp" in f]
    if leftovers:
        fail(f"temporary files left: {leftovers}")

    # Independent truths from the scene: the corner nodes (a tet10 mesh appends its edge nodes after them) and the
    # tet count (tet10: each element exported as its 8 linear tets).
    corners = rest_nodes(scene["mesh"])
    m = scene["mesh"]
    quadratic = m.get("element") == "tet10"
    n_tets = 6 * m["segments_around"] * m["segments_along"] * m["layers"] * (8 if quadratic else 1)
    young, nu = scene["material"]["young_modulus"], scene["material"]["poisson_ratio"]
    max_vm_err, max_rest_err, contact_frames = 0.0, 0.0, 0
    for ds, rec in zip(sets, frames):
        if abs(float(ds.get("timestep")) - rec["t"]) > 1e-12:
            fail(f"{ds.get('file')}: timestep {ds.get('timestep')}, the report's t {rec['t']}")
        vol = meshio.read(os.path.join(work, ds.get("file")))
        tets = vol.cells_dict.get("tetra")
        if tets is None or len(tets) != n_tets or len(vol.cells) != 1:
            fail(f"{ds.get('file')}: cells {[(c.type, len(c.data)) for c in vol.cells]}, expected {n_tets} tetra")
        used = len(np.unique(tets))
        if len(vol.points) != used or (len(vol.points) != len(corners)) != quadratic:
            fail(f"{ds.get('file')}: {len(vol.points)} points, {used} used by cells, {len(corners)} corners")
        u = vol.point_data["displacement"]
        rest = vol.points - u
        max_rest_err = max(max_rest_err, np.abs(rest[:len(corners)] - corners).max())
        vm = np.ravel(vol.cell_data["von_mises"][0])
        ref = von_mises(rest, u, tets, young, nu)
        max_vm_err = max(max_vm_err, (np.abs(vm - ref) / max(ref.max(), 1e-300)).max())
        flagged = set(np.nonzero(np.ravel(vol.point_data["contact"]))[0].tolist())
        inner = set(i for i in range(len(corners)) if (i // m["segments_around"]) % (m["layers"] + 1) == 0)
        if not quadratic and not flagged <= inner:
            fail(f"{ds.get('file')}: contact flags on non-inner-wall nodes {sorted(flagged - inner)[:10]}")
        if rec["contacts"] > 0 and not flagged:
            fail(f"{ds.get('file')}: the report has {rec['contacts']} contacts, no node is flagged")
        contact_frames += bool(flagged)
    if max_rest_err > 1e-12:
        fail(f"points - displacement differ from the rest mesh by {max_rest_err} m")
    if max_vm_err > VON_MISES_REL_TOL:
        fail(f"von Mises differs from the recomputation by {max_vm_err} (relative to the frame's largest)")
    if contact_frames == 0 and scene.get("collision", {}).get("self"):
        fail("no frame has a contact flag (the scene should close the lumen)")
    # The last frame's points are the --positions output.
    final = np.loadtxt(positions, delimiter=",")
    last = meshio.read(os.path.join(work, sets[-1].get("file")))
    if np.abs(last.points - final).max() > POSITION_TOL_M:
        fail(f"last frame's points differ from --positions by {np.abs(last.points - final).max()} m")
    print(f"check_volume_export: ok: {scene['name']}: {len(sets)} frames, {len(last.points)} nodes, {n_tets} tets, rest error "
          f"{max_rest_err:.2e} m, von Mises relative error {max_vm_err:.2e}, {contact_frames} frames with contact "
          f"flags, max displacement {np.abs(last.point_data['displacement']).max():.3e} m")


if __name__ == "__main__":
    main()
