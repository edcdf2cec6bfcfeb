#!/usr/bin/python3
"""Plot of the study against the converged CalculiX reference (issue 9): the inner wall's full-field error
(relative L2 of its displacement against the reference's) against the whole frame's median time, one point per
configuration, each family (model, element, uniform or graded mesh) joined in order of refinement.

usage: tools/study_reference_plot.py --sweep docs/study_reference_field.csv [--sweep docs/study_reference_graded_field.csv]
           [--closure docs/study_closure_field.csv] --field-linear docs/reference_inner_wall_tip3mm_small.csv
           --field-neohooke docs/reference_inner_wall_tip3mm_large.csv --out docs/study_reference.png

Panels: the small pinch (0.002 N) against the linear reference (each configuration's discretisation error, for the
linear model); the large pinch below contact (0.01 N) against the Neo-Hookean NLGEOM reference (the whole error:
discretisation and model), with the linear model's own error drawn as a line: the converged linear field (scaled to
0.01 N) against the converged Neo-Hookean one on the reference's grid, which no linear configuration can beat; and,
when --closure is given, the pinch past closure (0.03 N) against the reference with contact.
"""
import argparse
import csv
import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from study_plot import finish_axes, save  # noqa: E402

STYLES = {("tet4", "linear"): ("o", "tab:blue"), ("tet4", "corotational"): ("s", "tab:orange"),
          ("tet10", "linear"): ("^", "tab:green"), ("tet10", "corotational"): ("D", "tab:red")}


def read_rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(line for line in f if not line.startswith("#")))


def read_field(path):
    """(force, {(x, y, z): (ux, uy, uz)}) of a reference_inner_wall CSV; exits naming the file when it is bad."""
    force, nodes = None, {}
    with open(path) as f:
        for number, line in enumerate(f, 1):
            if line.startswith("#"):
                if force is None and "F = " in line:
                    try:
                        force = float(line.split("F = ")[1].split()[0])
                    except (ValueError, IndexError):
                        raise SystemExit(f"{path}:{number}: 'F = ' is not followed by a number of newtons")
                continue
            if line.startswith("x_m"):
                continue
            try:
                v = [float(c) for c in line.split(",")]
                nodes[tuple(round(c, 9) for c in v[:3])] = v[3:6]
            except (ValueError, IndexError):
                raise SystemExit(f"{path}:{number}: not six numbers")
    if force is None:
        raise SystemExit(f"{path}: no 'F = <newtons> N' in its comment lines")
    return force, nodes


def model_error(linear_path, neohooke_path):
    """The linear model's own error at the Neo-Hookean field's force: the relative L2 over the wall of the linear
    field scaled to that force against the Neo-Hookean one, both on the same grid (equal weights on a grid is not the
    trapezoid rule: the grids are graded, so the nodes are weighted by their cell's extent)."""
    f_lin, lin = read_field(linear_path)
    f_nh, nh = read_field(neohooke_path)
    if set(lin) != set(nh):
        raise SystemExit(f"{linear_path}, {neohooke_path}: not the same grid of nodes")
    angle = sorted({math.atan2(k[1], k[0]) for k in nh})
    zs = sorted({k[2] for k in nh})

    def weights(x, period):
        n = len(x)
        w = []
        for i in range(n):
            before = x[i] - x[i - 1] if i > 0 else (x[0] + period - x[-1] if period else 0.0)
            after = x[i + 1] - x[i] if i + 1 < n else (x[0] + period - x[-1] if period else 0.0)
            w.append(0.5 * (before + after))
        return w

    wa = dict(zip(angle, weights(angle, 2.0 * math.pi)))
    wz = dict(zip(zs, weights(zs, 0.0)))
    err2 = ref2 = 0.0
    s = f_nh / f_lin
    for k, u in nh.items():
        w = wa[math.atan2(k[1], k[0])] * wz[k[2]]
        err2 += w * sum((s * a - b) ** 2 for a, b in zip(lin[k], u))
        ref2 += w * sum(b * b for b in u)
    return math.sqrt(err2 / ref2), f_nh


def family(row):
    graded = float(row.get("grade_around") or 1.0) != 1.0
    return (row["element"], row["model"], graded)


def panel(ax, rows, key, title, model_line=None):
    groups = {}
    for r in rows:
        if r.get(key):
            groups.setdefault(family(r), []).append(r)
    for (element, model, graded), rs in sorted(groups.items()):
        rs.sort(key=lambda r: int(r["nodes"]))
        marker, colour = STYLES.get((element, model), ("x", "black"))
        ts = [float(r["total_median_ms"]) for r in rs]
        es = [float(r[key]) for r in rs]
        name = f"{model} {element}{' graded' if graded else ''}"
        ax.plot(ts, es, ls="--" if graded else "-", marker=marker, color=colour, mfc="none" if graded else colour,
                label=name, zorder=3)
        for r, t, e in zip(rs, ts, es):
            ax.annotate(f"{r['around']}x{r['along']}x{r['layers']}", (t, e), textcoords="offset points",
                        xytext=(4, 3), fontsize=6)
    if model_line is not None:
        ax.axhline(model_line, color="tab:blue", lw=0.8, ls="-.",
                   label=f"linear model's own error ({100 * model_line:.0f} %)")
    finish_axes(ax, title, "whole frame, median ms (physics + collision + response + render 640x480)",
                "inner wall displacement, relative L2 error", legend_size=7)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sweep", action="append", required=True, help="a lumen_study --reference-out CSV")
    ap.add_argument("--closure", help="a lumen_study --closure-out CSV with its field_err column")
    ap.add_argument("--field-linear", required=True)
    ap.add_argument("--field-neohooke", required=True)
    ap.add_argument("--out", required=True)
    args = ap.parse_args()
    rows = [r for path in args.sweep for r in read_rows(path)]
    small = [r for r in rows if math.isclose(float(r["force_n"]), 0.002)]
    large = [r for r in rows if math.isclose(float(r["force_n"]), 0.01)]
    if not small or not large:
        raise SystemExit(f"{', '.join(args.sweep)}: rows at 0.002 N and 0.01 N needed")
    line, at = model_error(args.field_linear, args.field_neohooke)
    closure = read_rows(args.closure) if args.closure else []
    fig, axes = plt.subplots(1, 3 if closure else 2, figsize=(18 if closure else 12.5, 5.5))
    panel(axes[0], small, "field_err_vs_linear", "small pinch, 0.002 N per tip, against the linear reference "
          "(discretisation error)")
    panel(axes[1], large, "field_err_vs_neohooke", f"large pinch, {at:g} N per tip (below contact), against "
          "Neo-Hookean NLGEOM", model_line=line)
    if closure:
        force = float(closure[0]["force_n"])
        panel(axes[2], closure, "field_err", f"past closure, {force:g} N per tip, against Neo-Hookean with contact")
    save(fig, args.out)
    print(f"wrote {args.out}; the linear model's own error at {at:g} N: {100 * line:.1f} %")


if __name__ == "__main__":
    main()
