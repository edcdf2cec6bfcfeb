#!/usr/bin/env python3
"""Converged CalculiX reference for the paper tube pinch (issue 9).

Python 3 standard library only.  Needs CalculiX (`ccx`, Debian calculix-ccx 2.20).

Usage
-----
  tools/reference/ccx_reference.py small            # linear, F = 0.002 N
  tools/reference/ccx_reference.py large            # NLGEOM, F = 0.01 and 0.02 N, NH and SVK
  tools/reference/ccx_reference.py closure          # NLGEOM NH with inner-wall contact
  tools/reference/ccx_reference.py all              # the three above
  tools/reference/ccx_reference.py all --tiny       # one very coarse mesh each (CI, < 30 s)
Options: --levels 1,2,3  --out DIR (CSV output, default docs/)  --work DIR (ccx scratch)
         --closure-force F  --penalty K  --keep (keep the scratch directory)
ccx always runs as OMP_NUM_THREADS=1 CCX_NPROC_EQUATION_SOLVER=1, one at a time.
Results go to <out>/reference_convergence.csv (one row per case/force/material/level;
rows of the cases run are replaced, others kept) and <out>/reference_inner_wall_<case>.csv
(finest level).  Each CSV starts with a '# command: ...' line.
The full run (`all`) takes about 25 minutes on this machine (2 cores shared with builds):
small 20 s, large 10 min (its level 4 Neo-Hookean run is stopped by --timeout), closure 10 min.
Levels are integers (see LEVELS) or explicit meshes "NTHxNZxNR" (elements per quarter circle,
along the half length, through the wall), e.g. --levels 2,10x12x3,3.

The problem
-----------
Hollow cylinder along z: inner radius 0.010 m, outer 0.013 m, length 0.100 m; all DOFs
of the nodes at z = 0 and z = 0.1 fixed.  E = 5000 Pa, nu = 0.45.  Two tips at mid-length
on the outer wall, centres (0, +0.013, 0.05) pushed along -y and (0, -0.013, 0.05) along
+y, force F each (dead load, fixed direction).

Models (symmetry reductions; quarter and eighth are checked against each other and against
the full tube by test_reference.py):
- quarter: x >= 0, z <= 0.05, symmetry planes x = 0 (u_x = 0) and z = 0.05 (u_z = 0).  Both
  tips and both halves of the inner wall are in the model; the y-symmetry is not imposed but
  checked (the two tips must move the same).  Used by `closure --closure-model quarter`: a
  genuine contact pair between the upper and lower halves of the inner wall.
- eighth (small, large, closure by default): the quarter's y >= 0 half with u_y = 0 on
  y = 0, half the DOFs.  For closure the lower half is the mirror image of the upper one, so
  the upper inner wall meets the symmetry plane: contact with a fixed (rigid) plate whose
  top face is y = 0.  Frictionless, this is the same problem as the pair, restricted to
  y-symmetric solutions.  (The quarter pair model stalls on meshes finer than level 2 near
  F = 0.011 N, below contact, where the eighth model does not: see the report in
  docs/reference_convergence.csv, rows 'neohooke-pair'.)
Loads on the model are F/4 per (quarter) tip; all reported quantities are those of the full
tube (the inner-wall CSV is mirrored out to the full tube).  Symmetric (non-bifurcated)
solutions only: a mode breaking the x-, y- or z-symmetry is excluded by construction.

Mesh: structured in (theta, r, z), theta from +x towards +y, theta in [-90, 90] deg,
geometric grading towards the tips in theta (ratio QTH largest/smallest element) and in z
(ratio QZ), uniform layers in r.  Each hex is split into 6 tets (Kuhn / Freudenthal split
along the hex diagonal from its lowest-index to its highest-index corner: conforming);
hexes with theta < 0 use the mirror split, so the mesh is exactly mirror-symmetric in y.
Quadratic C3D10: every node (corner or edge midpoint) is a node of the doubled
(theta, r, z) grid mapped through x = r cos(theta), y = r sin(theta): midside nodes of
edges along theta lie on the true circle; all edges are the images of straight lines in
(theta, r, z) (isoparametric in cylinder coordinates).  Level L has 4L elements per
quarter circle in theta, 5L along z (half length) and L layers.

Tip (patch and load): the part of the outer wall (reference configuration) within 1.5 mm
(3D distance) of the tip centre.  Load = uniform traction t = F/A_patch along the pinch
direction over the patch: consistent nodal loads f_a = (F/A) * int_patch N_a dA over the
outer 6-node faces (N_a quadratic, isoparametric face geometry), the indicator of the disc
integrated by a 24x24 sub-triangle centroid rule per face; A_patch is computed by the same
rule, so the loads sum to F exactly (F/4 on the quarter).
Tip displacement = area-weighted mean over the patch of u . d (d = pinch direction,
positive inward) = sum_a (f_a / F) u_a . d with the same weights (the work-conjugate
mean).  Reported: top tip (column tip_displacement_m) and bottom tip (tip_bottom_m).
Opening: opening_m = the deformed y-gap between the inner wall's upper and lower nodes at
x = 0, z = 0.05 (the centre of the lumen under the tips), negative = penetration (penalty
contact, or, in the contact-free `large` case, walls that would have touched).
opening_min_m = min over the inner wall's mirror node pairs (x, +-y, z) with reference
|theta| >= 60 deg (|x| <= r/2, the flattened part; the halves join at theta = 0, where the
gap is 0 by geometry) of the same y-gap: it differs from opening_m when the walls close
off-centre (a dog-bone lumen).

Cases
-----
small   : linear material, linear analysis, F = 0.002 N (levels 1..5).
large   : NLGEOM, two steps F = 0.01 then 0.02 N (each ramped in increments <= 0.05 of the
          step), (a) compressible Neo-Hookean, C10 = mu/2, D1 = 2/K (ccx: W = C10 (I1b - 3)
          + (J - 1)^2 / D1), mu = E / (2 (1 + nu)), K = E / (3 (1 - 2 nu)); (b) the linear
          material under NLGEOM = St Venant-Kirchhoff.  Levels 1..4.
closure : NLGEOM Neo-Hookean, two steps: F = 0.02 N (about first contact) then
          --closure-force (default 0.025 N); increments: step 1 initial 0.2, max 0.5; step 2
          initial 0.05, max 0.1.  Frictionless surface-to-surface penalty contact (ccx TYPE=
          SURFACE TO SURFACE), slave = the upper half of the inner wall with reference
          theta >= 30 deg (faces near theta = 0, where the halves join, must not be paired),
          master = the rigid plate y = 0 (eighth) or the lower half (quarter, slave = lower,
          master = upper, both |theta| >= 30 deg).  Linear pressure-overclosure, slope K =
          --penalty (default 1e8 Pa/m, about 10 E/h at the finest tip elements), checked by one
          run at 10 K on the finest level (material '...-K10').  contact_force_N = |normal
          force| on the slave surface from ccx's *CONTACT PRINT CF output ("area, normal force
          (+ = tension) and shear force"), x 4 for the full tube; contact_area_m2 = ccx's slave
          contact area x 4.  first_contact_N = the load at which opening_min first reaches 0
          (linear interpolation between increments; the load ramps linearly in a step).

Refinement: levels 1, 2, 3, ...; stop when the tip displacement of every force changes by
< 1% between the last two levels (from level 3 on), when a run fails, or after a run took
longer than --budget seconds.
"""
import argparse
import math
import os
import re
import shutil
import subprocess
import sys
import time

RI, RO, LEN = 0.010, 0.013, 0.100
ZMID = LEN / 2
E_MOD, NU = 5000.0, 0.45
TIP_R = 0.0015
QTH, QZ = 6.0, 12.0
SUBDIV = 24
CONTACT_THETA = math.radians(30.0)  # contact surfaces: inner wall with |theta| >= 30 deg
OPEN_THETA = math.radians(60.0)   # opening: pairs with |x_ref| <= r cos 60 deg
LEVELS = {L: (4 * L, 5 * L, L) for L in range(1, 7)}
CCX = os.environ.get("CCX", "ccx")

MU = E_MOD / (2 * (1 + NU))
KBULK = E_MOD / (3 * (1 - 2 * NU))
C10 = MU / 2
D1 = 2 / KBULK


# ----------------------------------------------------------------------------- mesh
def graded(a, b, n, q):
    """n+1 points from a to b; element sizes geometric, ratio q (largest at a, smallest at b)."""
    if n == 1:
        return [a, b]
    s = [q ** (-k / (n - 1)) for k in range(n)]
    tot = sum(s)
    pts = [a]
    for h in s:
        pts.append(pts[-1] + (b - a) * h / tot)
    pts[-1] = b
    return pts


def doubled(c):
    """Corner coordinates -> doubled grid (midpoints are parametric averages)."""
    out = []
    for i in range(len(c) - 1):
        out += [c[i], 0.5 * (c[i] + c[i + 1])]
    out.append(c[-1])
    return out


class Mesh:
    def __init__(self, level, tiny=False, full=False, eighth=False):
        self.level = level
        if tiny:
            nth, nz, nr = 2, 3, 1
        elif isinstance(level, tuple):
            nth, nz, nr = level
        else:
            nth, nz, nr = LEVELS[level]
        self.nth, self.nz, self.nr = nth, nz, nr
        half = graded(0.0, math.pi / 2, nth, QTH)
        th = [-t for t in reversed(half[1:])] + half          # 2 nth + 1 corners
        self.TH = doubled(th)
        self.R = doubled([RI + (RO - RI) * j / nr for j in range(nr + 1)])
        self.Z = doubled(graded(0.0, ZMID, nz, QZ))
        self.NI, self.NJ, self.NK = len(self.TH), len(self.R), len(self.Z)
        self.elements = []   # list of 10 grid-index triples
        for k in range(nz):
            for j in range(nr):
                for i in range(nth if eighth else 0, 2 * nth):
                    self._hex(i, j, k, mirror=(i < nth))
        used = {}
        for el in self.elements:
            for g in el:
                if g not in used:
                    used[g] = None
        self.full = full
        self.eighth = eighth
        self.MID = (self.NI - 1) // 2
        self.load_fraction = 0.25
        if full:   # mirror the quarter in x and z (check of the symmetry reduction)
            els = []
            for sx in (1, -1):
                for sz in (1, -1):
                    for el in self.elements:
                        ks = [self.key(g, sx, sz) for g in el]
                        if sx * sz < 0:
                            ks = [ks[i] for i in (1, 0, 2, 3, 4, 6, 5, 8, 7, 9)]
                        els.append(ks)
            self.elements = els
            used = {k: None for el in els for k in el}
            self.load_fraction = 1.0
        self.nid = {}
        for g in sorted(used, key=lambda g: (g[2], g[1], g[0]) + tuple(g[3:])):
            self.nid[g] = len(self.nid) + 1
        self.dofs = 3 * len(self.nid)

    def key(self, g, sx, sz):
        g = tuple(g[:3])
        return g + (1 if g[0] in (0, self.NI - 1) else sx, 1 if g[2] == self.NK - 1 else sz)

    def mirror_y(self, g):
        return (self.NI - 1 - g[0],) + tuple(g[1:])

    def xyz(self, g):
        I, J, K = g[:3]
        t, r = self.TH[I], self.R[J]
        x = 0.0 if I in (0, self.NI - 1) else r * math.cos(t)
        if len(g) == 5:
            return (g[3] * x, r * math.sin(t), self.Z[K] if g[4] > 0 else LEN - self.Z[K])
        return (x, r * math.sin(t), self.Z[K])

    def _hex(self, i, j, k, mirror):
        def corner(a, b, c):
            ii = (i + 1 - a) if mirror else (i + a)
            return (2 * ii, 2 * (j + b), 2 * (k + c))
        for perm in ((0, 1, 2), (0, 2, 1), (1, 0, 2), (1, 2, 0), (2, 0, 1), (2, 1, 0)):
            bits = [0, 0, 0]
            vs = [corner(*bits)]
            for ax in perm:
                bits[ax] = 1
                vs.append(corner(*bits))
            p = [self.xyz(v) for v in vs]
            if vol(p) < 0:
                vs[1], vs[2] = vs[2], vs[1]
            m = lambda a, b: tuple((vs[a][d] + vs[b][d]) // 2 for d in range(3))
            self.elements.append(vs + [m(0, 1), m(1, 2), m(2, 0), m(0, 3), m(1, 3), m(2, 3)])

    # ccx C3D10 faces: S1 1-2-3, S2 1-4-2, S3 2-4-3, S4 3-4-1 (corner, corner, corner, mids)
    FACES = ((0, 1, 2, 4, 5, 6), (0, 3, 1, 7, 8, 4), (1, 3, 2, 8, 9, 5), (2, 3, 0, 9, 7, 6))

    def faces_on(self, J):
        out = []
        for e, el in enumerate(self.elements):
            for f, fc in enumerate(self.FACES):
                if all(el[c][1] == J for c in fc[:3]):
                    out.append((e + 1, f + 1, [el[c] for c in fc]))
        return out


def vol(p):
    a = [p[1][d] - p[0][d] for d in range(3)]
    b = [p[2][d] - p[0][d] for d in range(3)]
    c = [p[3][d] - p[0][d] for d in range(3)]
    return (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
            + a[2] * (b[0] * c[1] - b[1] * c[0])) / 6


def t6(xi, eta):
    ze = 1 - xi - eta
    N = (ze * (2 * ze - 1), xi * (2 * xi - 1), eta * (2 * eta - 1), 4 * xi * ze, 4 * xi * eta, 4 * eta * ze)
    dxi = (-(4 * ze - 1), 4 * xi - 1, 0.0, 4 * (ze - xi), 4 * eta, -4 * eta)
    deta = (-(4 * ze - 1), 0.0, 4 * eta - 1, -4 * xi, 4 * xi, 4 * (ze - eta))
    return N, dxi, deta


def subpoints(m):
    """Centroids and weights of an m x m subdivision of the reference triangle."""
    pts = []
    w = 0.5 / (m * m)
    for a in range(m):
        for b in range(m - a):
            pts.append(((a + 1 / 3) / m, (b + 1 / 3) / m, w))
            if a + b < m - 1:
                pts.append(((a + 2 / 3) / m, (b + 2 / 3) / m, w))
    return pts


def tip_weights(mesh, centre):
    """{grid node: int N_a dA over the patch}, patch area.  See the module docstring."""
    outer = mesh.faces_on(mesh.NJ - 1)
    sp = subpoints(SUBDIV)
    w = {}
    area = 0.0
    for _, _, nodes in outer:
        P = [mesh.xyz(g) for g in nodes]
        if min(math.dist(p, centre) for p in P) > TIP_R + max(math.dist(P[0], p) for p in P):
            continue
        for xi, eta, wt in sp:
            N, dx, de = t6(xi, eta)
            x = [sum(N[a] * P[a][d] for a in range(6)) for d in range(3)]
            if math.dist(x, centre) > TIP_R:
                continue
            tx = [sum(dx[a] * P[a][d] for a in range(6)) for d in range(3)]
            te = [sum(de[a] * P[a][d] for a in range(6)) for d in range(3)]
            cr = (tx[1] * te[2] - tx[2] * te[1], tx[2] * te[0] - tx[0] * te[2], tx[0] * te[1] - tx[1] * te[0])
            dA = math.sqrt(sum(c * c for c in cr)) * wt
            area += dA
            for a in range(6):
                w[nodes[a]] = w.get(nodes[a], 0.0) + N[a] * dA
    if area == 0.0:
        return {}, 0.0
    w = {g: v / area for g, v in w.items() if v != 0.0}      # normalised: sum = 1
    if mesh.full:
        wf = {}
        for g, v in w.items():
            for sx in (1, -1):
                for sz in (1, -1):
                    k = mesh.key(g, sx, sz)
                    wf[k] = wf.get(k, 0.0) + v / 4
        w = wf
    return w, area


# ----------------------------------------------------------------------------- input
def write_inp(path, mesh, case, forces, material, nlgeom, penalty=None, one_tip=False, frd=False):
    """forces: list of per-tip forces (full tube), one ccx step each."""
    L = []
    L.append("** Lumen paper tube quarter model, generated by tools/reference/ccx_reference.py")
    L.append("*NODE, NSET=NALL")
    for g, n in mesh.nid.items():
        x, y, z = mesh.xyz(g)
        L.append("%d, %.12e, %.12e, %.12e" % (n, x, y, z))
    L.append("*ELEMENT, TYPE=C3D10, ELSET=EALL")
    for e, el in enumerate(mesh.elements):
        ids = [mesh.nid[g] for g in el]
        L.append("%d, %s" % (e + 1, ", ".join(map(str, ids))))

    def nset(name, pred):
        ids = sorted(n for g, n in mesh.nid.items() if pred(g))
        L.append("*NSET, NSET=%s" % name)
        for s in range(0, len(ids), 16):
            L.append(", ".join(map(str, ids[s:s + 16])))
    nset("NFIX", lambda g: g[2] == 0)
    if not mesh.full:
        nset("NSYMZ", lambda g: g[2] == mesh.NK - 1)
        nset("NSYMX", lambda g: g[0] in (0, mesh.NI - 1))
    if mesh.eighth:
        nset("NSYMY", lambda g: g[0] == mesh.MID)
    nset("NINNER", lambda g: g[1] == 0)
    mid = (mesh.NI - 1) // 2
    inner = mesh.faces_on(0)
    ct = math.sin(CONTACT_THETA)
    for name, pred in (("SUP", lambda nodes: all(mesh.xyz(g)[1] >= ct * RI - 1e-12 for g in nodes[:3])),
                       ("SLO", lambda nodes: all(mesh.xyz(g)[1] <= -ct * RI + 1e-12 for g in nodes[:3]))):
        L.append("*SURFACE, NAME=%s, TYPE=ELEMENT" % name)
        for e, f, nodes in inner:
            if pred(nodes):
                L.append("%d, S%d" % (e, f))
    L.append("*MATERIAL, NAME=MAT")
    if material == "neohooke":
        L.append("*HYPERELASTIC, NEO HOOKE")
        L.append("%.12e, %.12e" % (C10, D1))
    else:
        L.append("*ELASTIC")
        L.append("%.12e, %.12e" % (E_MOD, NU))
    L.append("*SOLID SECTION, ELSET=EALL, MATERIAL=MAT")
    slave, master = "SLO", "SUP"
    if penalty and mesh.eighth:
        # eighth model: the lower half is the mirror image, so the upper inner wall meets the
        # symmetry plane y = 0: a fixed (rigid) plate of C3D8 elements, y in [-2 mm, 0], whose
        # top face is the master surface
        slave, master = "SUP", "SPLANE"
        n0, e0 = len(mesh.nid), len(mesh.elements)
        xs = [-0.002 + 0.002 * i for i in range(12)]          # -2 .. 20 mm
        zs = [-0.002 + 0.002 * k for k in range(28)]          # -2 .. 52 mm
        pid = lambda i, k, top: n0 + 1 + i + len(xs) * (k + len(zs) * top)
        L.append("*NODE, NSET=NPLANE")
        for top, y in ((0, -0.002), (1, 0.0)):
            for k, z in enumerate(zs):
                for i, x in enumerate(xs):
                    L.append("%d, %.12e, %.12e, %.12e" % (pid(i, k, top), x, y, z))
        L.append("*ELEMENT, TYPE=C3D8, ELSET=EPLANE")
        faces = []
        for k in range(len(zs) - 1):
            for i in range(len(xs) - 1):
                e = e0 + 1 + len(faces)
                q = [(i, k), (i, k + 1), (i + 1, k + 1), (i + 1, k)]   # (z, x) order: positive volume
                L.append("%d, %s" % (e, ", ".join(str(pid(a, b, t)) for t in (0, 1) for a, b in q)))
                faces.append(e)
        L.append("*SURFACE, NAME=SPLANE, TYPE=ELEMENT")
        L += ["%d, S2" % e for e in faces]
        L.append("*MATERIAL, NAME=RIGID")
        L.append("*ELASTIC")
        L.append("1e9, 0.3")
        L.append("*SOLID SECTION, ELSET=EPLANE, MATERIAL=RIGID")
    if penalty:
        L.append("*SURFACE INTERACTION, NAME=SI")
        L.append("*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=LINEAR")
        L.append("%.6e, %.6e" % (penalty, 1.0))
        L.append("*CONTACT PAIR, INTERACTION=SI, TYPE=SURFACE TO SURFACE")
        L.append("%s, %s" % (slave, master))
    L.append("*BOUNDARY")
    L.append("NFIX, 1, 3")
    if penalty and mesh.eighth:
        L.append("NPLANE, 1, 3")
    if not mesh.full:
        L.append("NSYMZ, 3, 3")
        L.append("NSYMX, 1, 1")
    if mesh.eighth:
        L.append("NSYMY, 2, 2")
    top, bot = mesh.tips
    for F in forces:
        if nlgeom:
            # contact-free ramps: initial 0.2, max 0.5 of the step; the step in which the walls
            # touch (F above first contact, ~0.0195 N): initial 0.05, max 0.1
            inc0, incmax = (0.05, 0.1) if (penalty and F > 0.02) else (0.2, 0.5)
            L.append("*STEP, NLGEOM, INC=1000")
            L.append("*STATIC")
            L.append("%g, 1.0, 1e-6, %g" % (inc0, incmax))
        else:
            L.append("*STEP")
            L.append("*STATIC")
        L.append("*CLOAD")
        for (w, area), sign in ((top, -1.0), (bot, 1.0)):
            if one_tip and sign > 0:
                continue
            for g in sorted(w, key=lambda g: mesh.nid[g]):
                L.append("%d, 2, %.12e" % (mesh.nid[g], sign * mesh.load_fraction * F * w[g]))
        L.append("*NODE PRINT, NSET=NINNER")
        L.append("U")
        if frd:
            L.append("*NODE FILE, NSET=NALL")
            L.append("U")
        L.append("*NODE PRINT, NSET=NTIP")
        L.append("U")
        L.append("*NODE PRINT, NSET=NFIX, TOTALS=ONLY")
        L.append("RF")
        if penalty:
            L.append("*CONTACT PRINT, SLAVE=%s, MASTER=%s" % (slave, master))
            L.append("CF")
        L.append("*END STEP")
    # the tip set must precede the steps: insert it before the material
    ids = sorted({mesh.nid[g] for w, _ in (top, bot) for g in w})
    at = L.index("*MATERIAL, NAME=MAT")
    L[at:at] = ["*NSET, NSET=NTIP"] + [", ".join(map(str, ids[s:s + 16])) for s in range(0, len(ids), 16)]
    with open(path, "w") as fh:
        fh.write("\n".join(L) + "\n")


# ----------------------------------------------------------------------------- run/parse
RUN_TIMEOUT = 480.0


def run_ccx(workdir, job):
    """Run ccx on one core; a run longer than RUN_TIMEOUT s is killed (its completed steps are kept)."""
    env = dict(os.environ, OMP_NUM_THREADS="1", CCX_NPROC_EQUATION_SOLVER="1")
    t0 = time.monotonic()
    with open(os.path.join(workdir, job + ".log"), "w") as log:
        try:
            rc = subprocess.run([CCX, "-i", job], cwd=workdir, env=env, stdout=log, stderr=subprocess.STDOUT,
                                timeout=RUN_TIMEOUT).returncode
        except subprocess.TimeoutExpired:
            rc = -9
    dt = time.monotonic() - t0
    logtxt = open(os.path.join(workdir, job + ".log")).read()
    return dt, rc, logtxt


NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[EeDd][-+]?\d+)?"


def parse_dat(path):
    """-> list of blocks {'kind', 'set', 'time', 'rows': {node: [values]} or 'totals': [..]}."""
    blocks = []
    cur = None
    hdr = re.compile(r"^\s*(displacements|forces|total force|statistics for slave set|contact)"
                     r".*?(?:for set|set)\s+(\S+).*?time\s+(" + NUM + r")", re.I)
    with open(path) as fh:
        for line in fh:
            s = line.strip()
            if not s:
                continue
            m = hdr.match(line)
            if m:
                cur = {"kind": m.group(1).lower(), "set": m.group(2).upper(), "time": float(m.group(3)),
                       "rows": {}, "lines": []}
                blocks.append(cur)
                continue
            if cur is None:
                continue
            parts = s.split()
            try:
                vals = [float(v.replace("D", "E")) for v in parts]
            except ValueError:
                cur["lines"].append(s)
                continue
            cur["lines"].append(s)
            if cur["kind"] == "displacements" and len(vals) == 4:
                cur["rows"][int(vals[0])] = vals[1:]
            else:
                cur.setdefault("nums", []).append(vals)
    return blocks


def parse_frd(path):
    """-> (coords {node: xyz}, list of displacement blocks {node: u})."""
    coords, disp = {}, []
    mode = None
    with open(path) as fh:
        for line in fh:
            if line.startswith("    2C"):
                mode = "C"
                continue
            if line.startswith(" -4  DISP"):
                mode = "D"
                disp.append({})
                continue
            if line.startswith(" -3"):
                mode = None
                continue
            if line.startswith(" -1") and mode in ("C", "D"):
                n = int(line[3:13])
                vals = [float(line[13 + 12 * i:25 + 12 * i]) for i in range(3)]
                if mode == "C":
                    coords[n] = vals
                else:
                    disp[-1][n] = vals
    return coords, disp


def step_blocks(blocks, kind, setname, nsteps):
    """The last block of each step (blocks come in time order; a step's last block is the one
    before the time reaches the next step's first, or the file's last)."""
    bl = [b for b in blocks if b["kind"].startswith(kind) and b["set"] == setname]
    if not bl:
        return []
    # ccx prints the total time; step s ends at time s
    out = []
    for s in range(1, nsteps + 1):
        c = [b for b in bl if b["time"] <= s + 1e-9]
        out.append(c[-1] if c and abs(c[-1]["time"] - s) < 1e-6 else None)
    return out


def measures(mesh, U_inner, U_tip):
    top, bot = mesh.tips
    res = {}
    for key, (w, area), sign in (("tip", top, -1.0), ("tip_bottom", bot, 1.0)):
        res[key] = sum(w[g] * sign * U_tip[mesh.nid[g]][1] for g in w) if U_tip else None
    if mesh.eighth:
        res["tip_bottom"] = res["tip"]
    mid = (mesh.NI - 1) // 2
    best = None
    for g, n in mesh.nid.items():
        if g[1] != 0 or g[0] <= mid or mesh.TH[g[0]] < OPEN_THETA:
            continue
        gm = mesh.mirror_y(g)
        yu = mesh.xyz(g)[1] + U_inner[n][1]
        yl = -yu if mesh.eighth else mesh.xyz(gm)[1] + U_inner[mesh.nid[gm]][1]
        gap = yu - yl
        if best is None or gap < best:
            best = gap
        if g[0] == mesh.NI - 1 and g[2] == mesh.NK - 1 and tuple(g[3:]) in ((), (1, 1)):
            res["opening_centre"] = gap
    res["opening_min"] = best
    res["opening"] = res["opening_centre"]
    return res


def parse_contact(blocks, nsteps):
    """ccx 2.20 '*CONTACT PRINT / CF' prints per slave set: total force (fx,fy,fz) and moment,
    centre of gravity and mean normal, moment about it, and 'area, normal force (+ = tension)
    and shear force (size)'.  Quarter model -> full tube: the contact force on the upper
    half-wall is |normal force| x 4 (quarter holds a quarter of the contact area); the area x 4."""
    out = []
    bl = [b for b in blocks if b["kind"].startswith("statistics")]
    for s in range(1, nsteps + 1):
        c = [b for b in bl if b["time"] <= s + 1e-9]
        if not c or abs(c[-1]["time"] - s) > 1e-6:
            out.append((None, None))
            continue
        nums = c[-1].get("nums", [])
        # the area line is the last numeric line with 3 numbers
        three = [v for v in nums if len(v) == 3]
        area, fn = (three[-1][0], three[-1][1]) if three else (None, None)
        if fn is None or math.isnan(fn) or area is None or math.isnan(area) or area == 0.0:
            out.append((0.0, 0.0))        # no contact element (ccx prints NaN)
        else:
            out.append((abs(fn) * 4, area * 4))
    return out


# ----------------------------------------------------------------------------- driver
def load_at(t, forces):
    """Per-tip force at total time t: step s (time s-1..s) ramps linearly forces[s-2] -> forces[s-1]."""
    if t <= 0:
        return 0.0
    st = min(max(int(math.ceil(t - 1e-9)), 1), len(forces))
    f0 = forces[st - 2] if st >= 2 else 0.0
    return f0 + min(t - (st - 1), 1.0) * (forces[st - 1] - f0)

def solve(level, forces, material, nlgeom, workdir, tiny=False, penalty=None, one_tip=False, job=None,
          keep_frd=False, full=False, eighth=False):
    mesh = Mesh(level, tiny, full, eighth)
    mesh.tips = (tip_weights(mesh, (0.0, RO, ZMID)), tip_weights(mesh, (0.0, -RO, ZMID)))
    job = job or "tube"
    os.makedirs(workdir, exist_ok=True)
    write_inp(os.path.join(workdir, job + ".inp"), mesh, None, forces, material, nlgeom, penalty, one_tip,
              frd=keep_frd)
    dt, rc, log = run_ccx(workdir, job)
    blocks = parse_dat(os.path.join(workdir, job + ".dat")) if os.path.exists(
        os.path.join(workdir, job + ".dat")) else []
    ns = len(forces)
    inner = step_blocks(blocks, "displacements", "NINNER", ns)
    tip = step_blocks(blocks, "displacements", "NTIP", ns)
    rf = step_blocks(blocks, "total force", "NFIX", ns)
    cont = parse_contact(blocks, ns) if penalty else [(None, None)] * ns
    # first contact: load at which the gap first reaches 0, linear interpolation between the
    # increments (the load ramps linearly within a step: F(t) at total time t)
    series = []
    for b in blocks:
        if b["kind"] == "displacements" and b["set"] == "NINNER" and len(b["rows"]) == len(
                [g for g in mesh.nid if g[1] == 0]):
            series.append((load_at(b["time"], forces), measures(mesh, b["rows"], None)["opening_min"]))
    first_contact = None
    for (f0, g0), (f1, g1) in zip([(0.0, 2 * RI)] + series, series):
        if g0 > 0 >= g1:
            first_contact = f0 + (f1 - f0) * g0 / (g0 - g1)
            break
    results = []
    for s in range(ns):
        r = {"force": forces[s], "dofs": mesh.dofs, "seconds": dt, "status": "ok", "first_contact": first_contact}
        if inner[s] is None or tip[s] is None:
            last = max([b["time"] for b in blocks] or [0.0])
            r["status"] = "%s(reached F=%.4g N)" % ("timeout" if rc == -9 else "failed", load_at(last, forces))
            results.append(r)
            continue
        r.update(measures(mesh, inner[s]["rows"], tip[s]["rows"]))
        r["inner"] = inner[s]["rows"]
        r["rf"] = rf[s]["nums"][0] if rf[s] and rf[s].get("nums") else None
        r["contact_force"], r["contact_area"] = cont[s]
        if penalty and r["opening_min"] < 0 and not r["contact_force"]:
            # the walls cross but ccx generated no contact element (seen on the coarsest mesh)
            r["status"] = "no_contact_detected"
        results.append(r)
    return mesh, results, log


def inner_csv(path, mesh, U, command, what=""):
    """Inner-wall nodes of the full tube (quarter mirrored in x and z), reference coordinates
    and displacement."""
    rows = {}
    for g, n in mesh.nid.items():
        if g[1] != 0:
            continue
        x, y, z = mesh.xyz(g)
        ux, uy, uz = U[n]
        for sx in (1, -1):
            for sz in (1, -1):
                for sy in ((1, -1) if mesh.eighth else (1,)):
                    X, Y, Z = sx * x, sy * y, (z if sz > 0 else LEN - z)
                    key = (round(X, 12), round(Y, 12), round(Z, 12))
                    rows[key] = (X, Y, Z, sx * ux, sy * uy, sz * uz)
    with open(path, "w") as fh:
        fh.write("# command: %s\n" % command)
        fh.write("# %s; level %s, %d DOFs; inner wall (r = %g m) of the full tube, reference coordinates "
                 "and displacement\n" % (what, mesh.level, mesh.dofs, RI))
        fh.write("x_m,y_m,z_m,ux_m,uy_m,uz_m\n")
        for k in sorted(rows, key=lambda k: (k[2], math.atan2(k[1], k[0]))):
            fh.write(",".join("%.6e" % v for v in rows[k]) + "\n")


FIELDS = ["case", "force_N", "material", "nlgeom", "level", "dofs", "tip_displacement_m", "opening_m",
          "contact_force_N", "contact_area_m2", "ccx_seconds", "tip_bottom_m", "opening_min_m",
          "penalty_Pa_per_m", "first_contact_N", "status"]


def fmt(v):
    if v is None:
        return ""
    if isinstance(v, float):
        return "%.6e" % v
    return str(v)


def write_convergence(path, rows, cases, command):
    """Rows of the (case, material, force) just run replace the old ones; others are kept."""
    done = {(r["case"], r["material"], fmt(r["force_N"])) for r in rows}
    old, prev_cmd = [], []
    if os.path.exists(path):
        with open(path) as fh:
            lines = [l.rstrip("\n") for l in fh if not l.startswith("#")]
        if lines and lines[0].split(",") == FIELDS:
            old = [l for l in lines[1:] if l and (lambda f: (f[0], f[2], f[1]))(l.split(",")) not in done]
        prev_cmd = [l.rstrip("\n") for l in open(path) if l.startswith("# command:")]
        prev_cmd = [c for c in prev_cmd if c != "# command: %s" % command]
    with open(path, "w") as fh:
        for c in prev_cmd:
            fh.write(c + "\n")
        fh.write("# command: %s\n" % command)
        fh.write(",".join(FIELDS) + "\n")
        for l in old:
            fh.write(l + "\n")
        for r in rows:
            fh.write(",".join(fmt(r.get(k)) for k in FIELDS) + "\n")


def rel(a, b):
    return abs(a - b) / abs(b) if (a is not None and b not in (None, 0)) else None


def run_series(case, levels, forces, material, nlgeom, args, penalty=None, tag=None, eighth=False,
               all_steps=False):
    """Refine over `levels`; stop early when converged (< 1%) at every force, or when a run fails
    or exceeds the time budget.  Returns rows and the finest successful (mesh, results)."""
    rows, finest, prev, finest_all = [], None, None, None
    for count, lv in enumerate(levels, 1):
        label = "x".join(map(str, lv)) if isinstance(lv, tuple) else str(lv)
        if QTH != 6.0 or QZ != 12.0:
            label += "_q%gx%g" % (QTH, QZ)
        mesh, res, log = solve(lv, forces, material, nlgeom, os.path.join(args.work, "%s_%s_L%s" % (
            case, tag or material, label)), tiny=args.tiny, penalty=penalty, eighth=eighth)
        for r in res:
            row = {"case": case, "force_N": r["force"], "material": tag or material, "nlgeom": int(nlgeom),
                   "level": "tiny" if args.tiny else label, "dofs": r["dofs"], "tip_displacement_m": r.get("tip"),
                   "opening_m": r.get("opening"), "contact_force_N": r.get("contact_force"),
                   "contact_area_m2": r.get("contact_area"), "ccx_seconds": round(r["seconds"], 2),
                   "tip_bottom_m": r.get("tip_bottom"), "opening_min_m": r.get("opening_min"),
                   "penalty_Pa_per_m": penalty, "status": r["status"],
                   "first_contact_N": r.get("first_contact")}
            rows.append(row)
            print("%-8s %-13s F=%-6g L=%s dofs=%-7d tip=%s opening=%s cf=%s area=%s t=%.1fs %s" % (
                case, tag or material, r["force"], row["level"], r["dofs"], fmt(r.get("tip")),
                fmt(r.get("opening")), fmt(r.get("contact_force")), fmt(r.get("contact_area")),
                r["seconds"], r["status"]), flush=True)
        ok = res[0]["status"] == "ok"      # refine on while the first load is reached
        if all(r["status"] == "ok" for r in res):
            finest_all = (mesh, res)
        if ok:
            changes = [rel(r["tip"], p["tip"]) for r, p in zip(res, prev) if r["status"] == "ok"
                       and p["status"] == "ok"] if prev else None
            finest = (mesh, res)
            prev = res
            if (changes and len(changes) == len(res) and all(c is not None and c < 0.01 for c in changes)
                    and count >= 3 and not args.all_levels):
                print("  converged: tip change %s" % ", ".join("%.3f%%" % (100 * c) for c in changes), flush=True)
                break
            if changes:
                print("  tip change vs previous level: %s" % ", ".join("%.3f%%" % (100 * c) for c in changes),
                      flush=True)
        else:
            break
        if res[0]["seconds"] > args.budget:
            print("  stopping refinement: last run took %.0f s (budget %.0f s)" % (res[0]["seconds"], args.budget),
                  flush=True)
            break
    return rows, (finest_all if all_steps else finest)


def main(argv=None):
    global QTH, QZ, RUN_TIMEOUT, TIP_R
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("case", choices=["small", "large", "closure", "all"])
    ap.add_argument("--tiny", action="store_true")
    ap.add_argument("--levels", default=None)
    ap.add_argument("--out", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "docs"))
    ap.add_argument("--work", default="/tmp/lumen_ccx_reference")
    ap.add_argument("--closure-force", type=float, default=0.025)
    ap.add_argument("--closure-model", choices=["eighth", "quarter"], default="eighth",
                    help="eighth: contact with the symmetry plane y = 0; quarter: upper/lower wall pair")
    ap.add_argument("--penalty", type=float, default=1e8)
    ap.add_argument("--large-forces", type=lambda v: [float(x) for x in v.split(",")], default=[0.01, 0.02])
    ap.add_argument("--grading", default="6,12", help="QTH,QZ: largest/smallest element ratios in theta, z")
    ap.add_argument("--timeout", type=float, default=RUN_TIMEOUT, help="kill a ccx run after this many s")
    ap.add_argument("--all-levels", action="store_true", help="run every level even when converged earlier")
    ap.add_argument("--budget", type=float, default=200.0, help="stop refining after a run longer than this (s)")
    ap.add_argument("--materials", default="neohooke,svk")
    ap.add_argument("--tip-radius", type=float, default=TIP_R, help="radius of each tip's disc, metres")
    args = ap.parse_args(argv)
    if not 0.0 < args.tip_radius < ZMID:
        ap.error(f"--tip-radius: must be in (0, {ZMID}) m (value {args.tip_radius})")
    TIP_R = args.tip_radius
    RUN_TIMEOUT = args.timeout
    QTH, QZ = (float(v) for v in args.grading.split(","))
    if shutil.which(CCX) is None:
        print("ccx not found", file=sys.stderr)
        return 2
    command = "tools/reference/ccx_reference.py " + " ".join(argv if argv is not None else sys.argv[1:])
    cases = ["small", "large", "closure"] if args.case == "all" else [args.case]
    if args.tiny and args.case == "all":
        cases = ["small", "large"]     # CI: linear + one NLGEOM Neo-Hookean at 0.01 N
    allrows = []
    out = os.path.abspath(args.out)
    os.makedirs(out, exist_ok=True)
    sfx = "_tiny" if args.tiny else ""
    for case in cases:
        if args.tiny:
            levels = [1]
        elif args.levels:
            levels = [tuple(int(x) for x in v.split("x")) if "x" in v else int(v) for v in args.levels.split(",")]
        else:
            levels = {"small": [1, 2, 3, 4, 5], "large": [1, 2, 3, 4], "closure": [1, 2, (10, 12, 3), 3]}[case]
        if case == "small":
            rows, fin = run_series(case, levels, [0.002], "linear", False, args, eighth=True)
            finals = [(fin, 0)]
        elif case == "large":
            rows, finals = [], []
            mats = args.materials.split(",") if not args.tiny else ["neohooke"]
            for mat in mats:
                r, fin = run_series(case, levels, [0.01] if args.tiny else args.large_forces,
                                    "neohooke" if mat == "neohooke" else "linear", True, args, tag=mat,
                                    eighth=True)
                rows += r
                if mat == "neohooke":
                    finals = [(fin, 0)]
        else:
            F = [0.02, args.closure_force]
            e8 = args.closure_model == "eighth"
            tag = "neohooke" if e8 else "neohooke-pair"
            rows, fin = run_series(case, levels, F, "neohooke", True, args, penalty=args.penalty, tag=tag,
                                   all_steps=True, eighth=e8)
            finals = [(fin, 1)]
            if fin is not None and not args.tiny:
                lv = fin[0].level
                r2, _ = run_series(case, [lv], F, "neohooke", True, args, penalty=10 * args.penalty,
                                   tag=tag + "-K10", eighth=e8)
                rows += r2
        allrows += rows
        for fin, s in finals:
            if fin is not None and fin[1][s]["status"] == "ok":
                inner_csv(os.path.join(out, "reference_inner_wall_%s%s.csv" % (case, sfx)), fin[0],
                          fin[1][s]["inner"], command, "case %s, F = %g N per tip" % (case, fin[1][s]["force"]))
    write_convergence(os.path.join(out, "reference_convergence%s.csv" % sfx), allrows, cases, command)
    return 0


if __name__ == "__main__":
    sys.exit(main())
