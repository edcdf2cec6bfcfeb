#!/usr/bin/python3
"""Plot of the speed-against-error study: error against frame time, one point per configuration, Pareto front
marked (the configurations no other one beats on both time and error).

usage: tools/study_plot.py docs/study.csv docs/study.png
Three panels: the small-deformation error (Lame cylinder), and the large-deformation errors of the pinch with
contact against its reference: the shape (the larger relative error of the probe displacement and the lumen
opening) and the contact (the larger relative error of the contact area and the total contact force).
"""
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def pareto(points):
    """Indices of the points (time, error) not dominated by another (lower or equal on both, lower on one)."""
    front = []
    for i, (t, e) in enumerate(points):
        dominated = any((t2 <= t and e2 <= e) and (t2 < t or e2 < e) for j, (t2, e2) in enumerate(points) if j != i)
        if not dominated:
            front.append(i)
    return sorted(front, key=lambda i: points[i][0])


def finish_axes(ax, title, xlabel, ylabel, legend_size=8):
    """A study panel's axes: the 25 ms budget marked, log-log, labelled, gridded, with its legend."""
    ax.axvline(25.0, color="red", lw=0.8, ls=":", label="25 ms budget")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.grid(True, which="both", lw=0.3)
    ax.legend(fontsize=legend_size)


def save(fig, dst):
    """The figure at dst, written under a temporary name and then renamed (never a half-written file)."""
    fig.tight_layout()
    tmp = dst + ".tmp.png"
    fig.savefig(tmp, dpi=110)
    os.replace(tmp, dst)


def label(row):
    lvl = f"{row['around']}x{row['layers']}"
    if row["model"] == "corotational":
        return f"{lvl} corot {float(row['tolerance']):g}"
    return f"{lvl} {row['model']} {row['element']}"


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    src, dst = sys.argv[1], sys.argv[2]
    with open(src, newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        sys.exit(f"{src}: no rows")
    styles = {("tet4", "linear"): ("o", "tab:blue", "linear tet4"),
              ("tet4", "corotational"): ("s", "tab:orange", "corotational tet4"),
              ("tet10", "linear"): ("^", "tab:green", "linear tet10")}
    fig, axes = plt.subplots(1, 3, figsize=(18, 5.5))
    for ax, key, title in ((axes[0], "lame_error", "small deformation: Lame cylinder (rel. L2 of u_r)"),
                           (axes[1], "err_shape", "pinch, shape: probe displacement, lumen opening"),
                           (axes[2], "err_contact", "pinch, contact: contact area, contact force")):
        pts = [(float(r["total_median_ms"]), max(float(r[key]), 1e-6)) for r in rows]
        seen = set()
        for r, (t, e) in zip(rows, pts):
            marker, colour, name = styles.get((r["element"], r["model"]), ("x", "black", r["model"]))
            ax.scatter(t, e, marker=marker, color=colour, label=None if name in seen else name, zorder=3)
            seen.add(name)
        front = pareto(pts)
        ax.plot([pts[i][0] for i in front], [pts[i][1] for i in front], "k--", lw=1, label="Pareto front", zorder=2)
        for i in front:
            ax.annotate(label(rows[i]), pts[i], textcoords="offset points", xytext=(5, 4), fontsize=7)
        finish_axes(ax, title, "frame time, median (ms): physics + collision + response + render 640x480",
                    "relative error")
    save(fig, dst)


if __name__ == "__main__":
    main()
