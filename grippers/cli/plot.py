"""``grippers plot FILE -o FILE.png|FILE.svg``: width, speed and force (or current) over time from a
recording (CSV, JSON Lines or MCAP), with the commands marked: the picture for tuning a grasp.

matplotlib is an optional dependency (``pip install 'grippers[plot]'``), imported inside :func:`run` only.
Any file that is not a recording, however malformed, ends in one line and exit code 2: :func:`read` checks
every row before anything is drawn. Commands that start at (nearly) the same moment share one label, so
their names never print over each other. SVG keeps its text as text (searchable, selectable).
"""

from __future__ import annotations

import argparse
from typing import Any

from .output import EXIT_OK, UsageError, write_json

HELP = "plot a recording (grippers record) to PNG or SVG: width, speed, force or current, commands marked"
EXAMPLE = "grippers plot grasp.csv -o grasp.png"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("recording", metavar="FILE", help="a recording: FILE.csv, FILE.jsonl or FILE.mcap")
    parser.add_argument("-o", "--output", required=True, metavar="IMAGE", help="IMAGE.png or IMAGE.svg")
    parser.add_argument("--title", help="the picture's title (default: the recorded URL)")
    parser.add_argument("--json", action="store_true", help="print what was drawn as JSON (docs/cli.md)")


def _series(rows: list[dict[str, Any]], key: str) -> tuple[list[float], list[float]]:
    xs, ys = [], []
    for row in rows:
        if row.get("kind") == "state" and row.get(key) is not None and row.get("t_s") is not None:
            xs.append(float(row["t_s"]))
            ys.append(float(row[key]))
    return xs, ys


LABEL_GAP = 0.025  # of the time axis: starts closer than this share one label


def label_groups(starts: list[tuple[float, str]], span: float) -> list[tuple[float, str]]:
    """Labels of command starts, those within ``LABEL_GAP`` of the axis of the previous one joined with
    " / " at the first one's time: a label is drawn rotated at its time, so two at one time overlap."""
    groups: list[tuple[float, list[str]]] = []
    for t, text in sorted(starts, key=lambda s: s[0]):
        if groups and t - groups[-1][0] <= LABEL_GAP * span:
            groups[-1][1].append(text)
        else:
            groups.append((t, [text]))
    return [(t, " / ".join(texts)) for t, texts in groups]


def run(args: argparse.Namespace) -> int:
    from .recording import RecordingError, read

    if not args.output.lower().endswith((".png", ".svg")):
        raise UsageError(f"{args.output}: the picture's name must end in .png or .svg")
    try:
        import matplotlib
    except ImportError:
        raise UsageError("grippers plot needs matplotlib: pip install 'grippers[plot]'") from None
    matplotlib.use("Agg")  # files only: no display needed on a bench machine or in CI
    matplotlib.rcParams["svg.fonttype"] = "none"  # SVG text stays text
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
    starts = [
        (float(row["t_s"]), str(row.get("command")) + (" (failed)" if row.get("phase") == "failed" else ""))
        for row in commands
        if row.get("phase") in ("start", "failed")
    ]
    times = [t for t in width[0]] + [t for t, _ in starts]
    span = (max(times) - min(times)) or 1.0
    for t, text in label_groups(starts, span):
        axes[0].annotate(
            text,
            (t, 1.0),
            xycoords=("data", "axes fraction"),
            rotation=90,
            va="top",
            ha="right",
            fontsize=8,
        )
    axes[-1].set_xlabel("time (s)")
    fig.suptitle(args.title or str(header.get("target", args.recording)))
    try:
        fig.savefig(args.output, dpi=100)
    except OSError as exc:
        raise UsageError(f"{args.output}: cannot write: {exc.strerror or exc}") from None
    except (ValueError, OverflowError) as exc:  # numbers matplotlib cannot place (finite, but 1e308 wide)
        raise UsageError(f"{args.recording}: cannot be drawn: {' '.join(str(exc).split())[:200]}") from None
    finally:
        plt.close(fig)
    if getattr(args, "json", False):
        write_json(
            {
                "schema": "grippers.plot/1",
                "recording": args.recording,
                "output": args.output,
                "states": len(width[0]),
                "commands": len(commands),
            }
        )
    else:
        print(f"wrote {args.output}")
    return EXIT_OK
