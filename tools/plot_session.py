#!/usr/bin/python3
"""Pictures of one Lumen session from its report.json (matplotlib from Debian: python3-matplotlib).

    tools/plot_session.py OUT/report.json [--out-dir DIR] [--prefix NAME]

writes two PNGs (into the report's directory unless --out-dir):
  NAME_reaction.png  force on each instrument (|F| and its x, y, z components, newtons) over session time;
                     a scene without instruments plots each probe's reaction force instead
  NAME_stages.png    frame time per stage (input, physics, collision, response, render), stacked per frame,
                     with the report's budget line (25 ms at 40 fps)
NAME defaults to "session". Exit 2 with a message naming the file and the field on a malformed report.
"""
import argparse
import json
import math
import os
import sys

# The report's per-frame stage keys, in pipeline order, and their colours in the stacked plot.
STAGES = [("input", "#8c8c8c"), ("physics", "#1f77b4"), ("collision", "#ff7f0e"),
          ("response", "#d62728"), ("render", "#2ca02c")]
COMPONENTS = [("x", ":"), ("y", "--"), ("z", "-.")]
FIGSIZE = (8.0, 4.5)  # inches
DPI = 110


class ReportError(Exception):
    pass


def field(obj, key, where):
    """obj[key], or a ReportError naming where it is missing."""
    if not isinstance(obj, dict) or key not in obj:
        raise ReportError(f"{where}: missing field '{key}'")
    return obj[key]


def vector3(value, where):
    if not (isinstance(value, list) and len(value) == 3 and all(isinstance(c, (int, float)) for c in value)):
        raise ReportError(f"{where}: expected a 3-vector, got {json.dumps(value)[:60]}")
    return [float(c) for c in value]


def load(path):
    try:
        with open(path, encoding="utf-8") as f:
            report = json.load(f)
    except OSError as e:
        raise ReportError(f"cannot read: {e.strerror}") from e
    except json.JSONDecodeError as e:
        raise ReportError(f"not JSON (line {e.lineno}, column {e.colno}): {e.msg}") from e
    frames = field(report, "per_frame", "report")
    if not isinstance(frames, list) or not frames:
        raise ReportError("per_frame: expected a non-empty array")
    return report, frames


def force_series(frames):
    """{label: (t [s], [F vectors])}: per instrument by name, else per probe index."""
    series = {}
    for i, fr in enumerate(frames):
        where = f"per_frame[{i}]"
        t = float(field(fr, "t", where))
        tools = fr.get("instruments", [])
        if tools:
            for k, tool in enumerate(tools):
                w = f"{where}.instruments[{k}]"
                name = str(field(tool, "name", w))
                series.setdefault(name, ([], []))
                series[name][0].append(t)
                series[name][1].append(vector3(field(tool, "force_n", w), w + ".force_n"))
        else:
            for k, f in enumerate(field(fr, "reaction_force_n", where)):
                name = f"probe {k}"
                series.setdefault(name, ([], []))
                series[name][0].append(t)
                series[name][1].append(vector3(f, f"{where}.reaction_force_n[{k}]"))
    return series


def plot_reaction(plt, frames, out_path):
    series = force_series(frames)
    fig, ax = plt.subplots(figsize=FIGSIZE)
    has_tools = any(fr.get("instruments") for fr in frames)
    for idx, (name, (t, forces)) in enumerate(series.items()):
        colour = f"C{idx % 10}"
        ax.plot(t, [math.sqrt(sum(c * c for c in f)) for f in forces], color=colour, lw=2.0, label=f"{name} |F|")
        for axis, (label, style) in enumerate(COMPONENTS):
            ax.plot(t, [f[axis] for f in forces], color=colour, lw=1.0, ls=style, label=f"{name} F{label}")
    ax.axhline(0.0, color="black", lw=0.5)
    ax.set_xlabel("session time (s)")
    ax.set_ylabel("force on the instrument (N)" if has_tools else "probe reaction force (N)")
    ax.set_title("Reaction force per instrument" if has_tools else "Reaction force per probe")
    if series:
        ax.legend(fontsize="small", ncol=2)
    else:
        ax.text(0.5, 0.5, "no instruments or probes in this session", transform=ax.transAxes, ha="center")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(out_path, dpi=DPI)
    plt.close(fig)


def plot_stages(plt, report, frames, out_path):
    budget = float(report.get("budget_ms", 25.0))
    index = [int(field(fr, "frame", f"per_frame[{i}]")) for i, fr in enumerate(frames)]
    fig, ax = plt.subplots(figsize=FIGSIZE)
    bottom = [0.0] * len(frames)
    for stage, colour in STAGES:
        key = stage + "_ms"
        ms = [float(field(fr, key, f"per_frame[{i}]")) for i, fr in enumerate(frames)]
        # A stage that took no time (render in a --no-render session) is left out of the bars and the legend.
        if not any(ms):
            continue
        ax.bar(index, ms, bottom=bottom, width=1.0, color=colour, label=stage, linewidth=0)
        bottom = [b + m for b, m in zip(bottom, ms)]
    ax.axhline(budget, color="black", ls="--", lw=1.2, label=f"budget {budget:g} ms")
    over = sum(1 for b in bottom if b > budget)
    ax.set_xlabel("frame")
    ax.set_ylabel("frame time (ms)")
    ax.set_title(f"Frame time per stage ({over} of {len(frames)} frames over budget)")
    ax.set_xlim(index[0] - 0.5, index[-1] + 0.5)
    ax.set_ylim(0.0, max(max(bottom), budget) * 1.15)
    ax.legend(fontsize="small", loc="upper right", ncol=3)
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    fig.savefig(out_path, dpi=DPI)
    plt.close(fig)


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("report", help="a session's report.json (lumen run ... --out DIR writes DIR/report.json)")
    ap.add_argument("--out-dir", help="directory for the PNGs (default: the report's directory)")
    ap.add_argument("--prefix", default="session", help="file name prefix (default: session)")
    args = ap.parse_args(argv)
    try:
        report, frames = load(args.report)
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        # Validate everything before writing anything.
        force_series(frames)
        for i, fr in enumerate(frames):
            for stage, _ in STAGES:
                float(field(fr, stage + "_ms", f"per_frame[{i}]"))
        out_dir = args.out_dir or os.path.dirname(os.path.abspath(args.report))
        os.makedirs(out_dir, exist_ok=True)
        paths = [os.path.join(out_dir, f"{args.prefix}_reaction.png"), os.path.join(out_dir, f"{args.prefix}_stages.png")]
        plot_reaction(plt, frames, paths[0])
        plot_stages(plt, report, frames, paths[1])
    except ReportError as e:
        print(f"plot_session: {args.report}: {e}", file=sys.stderr)
        return 2
    except ImportError as e:
        print(f"plot_session: needs matplotlib (Debian: apt-get install python3-matplotlib): {e}", file=sys.stderr)
        return 2
    for p in paths:
        print(p)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
