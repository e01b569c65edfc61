"""``grippers plot FILE -o FILE.png|FILE.svg``: width, speed and force (or current) over time from a
recording, with the commands marked: the picture for tuning a grasp.

matplotlib is an optional dependency (``pip install 'grippers[plot]'``), imported inside :func:`run` only.
"""

from __future__ import annotations

import argparse
from typing import Any

from .output import EXIT_OK, UsageError

HELP = "plot a recording (grippers record) to PNG or SVG: width, speed, force or current, commands marked"
EXAMPLE = "grippers plot grasp.csv -o grasp.png"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("recording", metavar="FILE", help="a recording: FILE.csv or FILE.jsonl")
    parser.add_argument("-o", "--output", required=True, metavar="IMAGE", help="IMAGE.png or IMAGE.svg")
    parser.add_argument("--title", help="the picture's title (default: the recorded URL)")


def _series(rows: list[dict[str, Any]], key: str) -> tuple[list[float], list[float]]:
    xs, ys = [], []
    for row in rows:
        if row.get("kind") == "state" and row.get(key) is not None and row.get("t_s") is not None:
            xs.append(float(row["t_s"]))
            ys.append(float(row[key]))
    return xs, ys


def run(args: argparse.Namespace) -> int:
    from .recording import RecordingError, read

    if not args.output.lower().endswith((".png", ".svg")):
        raise UsageError(f"{args.output}: the picture's name must end in .png or .svg")
    try:
        import matplotlib
    except ImportError:
        raise UsageError("grippers plot needs matplotlib: pip install 'grippers[plot]'") from None
    matplotlib.use("Agg")  # files only: no display needed on a bench machine or in CI
    import matplotlib.pyplot as plt

    try:
        header, rows = read(args.recording)
    except RecordingError as exc:
        raise UsageError(str(exc)) from None
    width = _series(rows, "width_mm")
    if not width[0]:
        raise UsageError(f"{args.recording}: no states recorded")
    force = _series(rows, "force_n")
    third = (force, "force (N)") if force[0] else (_series(rows, "current_a"), "current (A)")
    panels = [(width, "width (mm)"), (_series(rows, "speed_mm_s"), "speed (mm/s)"), third]
    fig, axes = plt.subplots(len(panels), 1, sharex=True, figsize=(10, 7), constrained_layout=True)
    commands = [r for r in rows if r.get("kind") == "command"]
    for ax, ((xs, ys), label) in zip(axes, panels, strict=True):
        ax.plot(xs, ys, color="tab:blue", linewidth=1.5)
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
        for row in commands:
            style = {"start": ("tab:green", "--"), "done": ("tab:gray", ":"), "failed": ("tab:red", "-")}
            color, line = style.get(str(row.get("phase")), ("tab:gray", ":"))
            ax.axvline(float(row["t_s"]), color=color, linestyle=line, linewidth=1)
    for row in commands:
        if row.get("phase") in ("start", "failed"):
            axes[0].annotate(
                str(row.get("command")) + (" (failed)" if row.get("phase") == "failed" else ""),
                (float(row["t_s"]), 1.0),
                xycoords=("data", "axes fraction"),
                rotation=90,
                va="top",
                ha="right",
                fontsize=8,
            )
    axes[-1].set_xlabel("time (s)")
    fig.suptitle(args.title or str(header.get("target", args.recording)))
    fig.savefig(args.output, dpi=100)
    plt.close(fig)
    print(f"wrote {args.output}")
    return EXIT_OK
