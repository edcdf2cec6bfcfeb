#!/usr/bin/env python3
"""CI test of the CalculiX reference pipeline (tools/reference/ccx_reference.py) on tiny meshes.

Exit 0: all checks passed; 1: a check failed; 77: `ccx` not installed (CTest SKIP_RETURN_CODE 77).
Runs in about 15 s.  Checks, each against a truth independent of the quantity checked:
  - the tiny pipeline (`all --tiny`) runs and writes both CSVs with their command line;
  - the loads written to the .inp sum to -F/4 and +F/4 (quarter model) per tip;
  - one tip loaded alone: the total y-reaction at the fixed end balances the load (the symmetry
    planes carry no y-reaction), and with both tips the y-reactions cancel;
  - the two tips move the same (the mesh is mirror-symmetric in y, y-symmetry is not imposed);
  - linear analysis at 2F gives twice the displacement;
  - Neo-Hookean under NLGEOM at F = 1e-5 N agrees with the linear analysis within 0.5%
    (checks the C10/D1 conversion from E, nu);
  - the quarter model with symmetry planes equals the full tube (mirrored mesh, no symmetry
    conditions) on the same mesh;
  - parsers: node coordinates in the .frd equal those written to the .inp, and the .frd and .dat
    displacements agree (two independent parsers of two ccx outputs);
  - the inner-wall CSV is consistent with the opening in the convergence CSV.
Tolerances of 1e-5 relative where ccx's printed precision (7 digits in .dat, 5 in .frd) limits.
"""
import csv
import math
import os
import shutil
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import ccx_reference as ref  # noqa: E402

failures = []


def check(name, ok, detail=""):
    print("%s  %s  %s" % ("PASS" if ok else "FAIL", name, detail), flush=True)
    if not ok:
        failures.append(name)


def rel(a, b):
    return abs(a - b) / max(abs(b), 1e-300)


def read_csv(path):
    with open(path) as fh:
        lines = fh.read().splitlines()
    comments = [l for l in lines if l.startswith("#")]
    rows = list(csv.DictReader(l for l in lines if not l.startswith("#")))
    return (comments[0] if comments else ""), rows


def cloads(inp):
    """The *CLOAD blocks of an .inp: one list of (node, value) per step."""
    steps, cur = [], None
    for line in open(inp):
        if line.startswith("*"):
            cur = [] if line.upper().startswith("*CLOAD") else None
            if cur is not None:
                steps.append(cur)
            continue
        if cur is not None:
            n, dof, v = line.split(",")
            assert int(dof) == 2
            cur.append((int(n), float(v)))
    return steps


def main():
    if shutil.which(ref.CCX) is None:
        print("SKIPPED: ccx not found")
        return 77
    tmp = tempfile.mkdtemp(prefix="lumen_ref_test_")
    try:
        work = os.path.join(tmp, "work")
        out = os.path.join(tmp, "out")
        # 1. the tiny pipeline
        rc = ref.main(["all", "--tiny", "--out", out, "--work", work])
        check("pipeline exit code", rc == 0, str(rc))
        conv = os.path.join(out, "reference_convergence_tiny.csv")
        first, rows = read_csv(conv)
        check("convergence CSV has its command", first.startswith("# command: tools/reference/ccx_reference.py"),
              first.strip())
        cases = {(r["case"], r["material"], float(r["force_N"])): r for r in rows}
        check("convergence CSV rows", ("small", "linear", 0.002) in cases and ("large", "neohooke", 0.01) in cases,
              str(sorted(cases)))
        for k, r in cases.items():
            check("status ok %s" % (k,), r["status"] == "ok", r["status"])
        tl = float(cases[("small", "linear", 0.002)]["tip_displacement_m"])
        tn = float(cases[("large", "neohooke", 0.01)]["tip_displacement_m"])
        check("tips move inward", tl > 0 and tn > 0, "%g %g" % (tl, tn))
        check("NH at 5F moves more than 5x linear (stiffness falls as the ring flattens)", tn > 5 * tl,
              "%g vs %g" % (tn, 5 * tl))

        # 2. inner-wall CSV against the opening of the convergence CSV
        first, iw = read_csv(os.path.join(out, "reference_inner_wall_small_tiny.csv"))
        check("inner-wall CSV has its command", first.startswith("# command:"))
        top = [r for r in iw if abs(float(r["x_m"])) < 1e-9 and abs(float(r["z_m"]) - 0.05) < 1e-9
               and float(r["y_m"]) > 0]
        bot = [r for r in iw if abs(float(r["x_m"])) < 1e-9 and abs(float(r["z_m"]) - 0.05) < 1e-9
               and float(r["y_m"]) < 0]
        ok = len(top) == 1 and len(bot) == 1
        if ok:
            gap = (float(top[0]["y_m"]) + float(top[0]["uy_m"])) - (float(bot[0]["y_m"]) + float(bot[0]["uy_m"]))
            op = float(cases[("small", "linear", 0.002)]["opening_m"])
            ok = rel(gap, op) < 1e-5
        check("inner-wall CSV centre gap = opening_m", ok, "%d %d" % (len(top), len(bot)))
        r0 = [r for r in iw if abs(float(r["z_m"])) < 1e-12]
        check("inner-wall CSV: fixed end does not move",
              len(r0) > 0 and all(abs(float(r[c])) < 1e-12 for r in r0 for c in ("ux_m", "uy_m", "uz_m")))

        F = 0.002
        # 3. loads and reactions, one tip
        d = os.path.join(work, "onetip")
        mesh, res, _ = ref.solve(1, [F], "linear", False, d, tiny=True, one_tip=True)
        loads = cloads(os.path.join(d, "tube.inp"))[0]
        loads = [v for _, v in loads]
        check("one-tip loads sum to -F/4", rel(sum(loads), -F / 4) < 1e-9, "%.9e" % sum(loads))
        rfy = res[0]["rf"][1]
        check("one tip: fixed-end y-reaction balances the load", rel(rfy, F / 4) < 1e-5, "%.6e vs %.6e" % (rfy, F / 4))

        # 4. both tips: symmetry, reaction, loads, parsers
        d = os.path.join(work, "pinch")
        mesh, res, _ = ref.solve(1, [F, 2 * F], "linear", False, d, tiny=True, keep_frd=True)
        step1 = cloads(os.path.join(d, "tube.inp"))[0]
        top_ids = {mesh.nid[g] for g in mesh.tips[0][0]}
        st = sum(v for nid, v in step1 if nid in top_ids)
        sb = sum(v for nid, v in step1 if nid not in top_ids)
        check("pinch loads: -F/4 and +F/4 per tip", rel(st, -F / 4) < 1e-9 and rel(sb, F / 4) < 1e-9,
              "%.9e %.9e" % (st, sb))
        a, b = res[0]["tip"], res[0]["tip_bottom"]
        check("tips move symmetrically", rel(a, b) < 1e-5, "%.9e %.9e" % (a, b))
        check("pinch: y-reactions cancel", abs(res[0]["rf"][1]) < 1e-5 * F, "%.3e" % res[0]["rf"][1])
        check("linear: 2F gives 2x", rel(res[1]["tip"], 2 * a) < 1e-5, "%.9e %.9e" % (res[1]["tip"], 2 * a))
        coords, disp = ref.parse_frd(os.path.join(d, "tube.frd"))
        err = max(math.dist(coords[nid], mesh.xyz(g)) for g, nid in mesh.nid.items())
        check("frd coordinates = inp coordinates", len(coords) == len(mesh.nid) and err < 1e-5 * ref.RO,
              "%d nodes, max err %.2e m" % (len(coords), err))
        blocks = ref.parse_dat(os.path.join(d, "tube.dat"))
        dat = ref.step_blocks(blocks, "displacements", "NINNER", 2)[0]["rows"]
        umax = max(abs(v) for u in dat.values() for v in u)
        derr = max(abs(disp[0][nid][c] - dat[nid][c]) for nid in dat for c in range(3))
        check("frd displacements = dat displacements", len(dat) > 0 and derr < 1e-4 * umax,
              "%d nodes, max diff %.2e of %.2e" % (len(dat), derr, umax))

        # 5. quarter with symmetry planes = full tube
        mesh_f, res_f, _ = ref.solve(1, [F], "linear", False, os.path.join(work, "full"), tiny=True, full=True)
        check("full tube is 4x the quarter's elements", len(mesh_f.elements) == 4 * len(mesh.elements))
        check("quarter model = full tube (tip)", rel(res_f[0]["tip"], a) < 1e-5, "%.9e %.9e" % (res_f[0]["tip"], a))
        check("quarter model = full tube (opening)", rel(res_f[0]["opening"], res[0]["opening"]) < 1e-6)

        _, res_e, _ = ref.solve(1, [F], "linear", False, os.path.join(work, "eighth"), tiny=True, eighth=True)
        check("eighth model (y-symmetry plane) = quarter model (tip)", rel(res_e[0]["tip"], a) < 1e-5,
              "%.9e %.9e" % (res_e[0]["tip"], a))
        check("eighth model = quarter model (opening)", rel(res_e[0]["opening"], res[0]["opening"]) < 1e-5)

        # 6. Neo-Hookean NLGEOM at small load = linear
        f = 1e-5
        _, rl, _ = ref.solve(1, [f], "linear", False, os.path.join(work, "lin_small"), tiny=True)
        _, rn, _ = ref.solve(1, [f], "neohooke", True, os.path.join(work, "nh_small"), tiny=True)
        check("NH NLGEOM at 1e-5 N = linear within 0.5%", rn[0]["status"] == "ok" and rel(rn[0]["tip"], rl[0]["tip"])
              < 0.005, "%.6e %.6e" % (rn[0].get("tip", float("nan")), rl[0]["tip"]))
        check("NH at 1e-5 N is not trivially equal to linear (NLGEOM is on)",
              rn[0]["status"] == "ok" and rel(rn[0]["tip"], rl[0]["tip"]) > 1e-9)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    if failures:
        print("FAILED: %d check(s): %s" % (len(failures), ", ".join(failures)))
        return 1
    print("all reference checks passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
