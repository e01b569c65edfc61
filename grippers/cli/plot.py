"""``grippers plot FILE... -o FILE.png|FILE.svg``: width, speed and force (or current) over time from one or
several recordings (CSV, JSON Lines or MCAP), every gripper in them a curve of its own on one time axis, with
the commands marked: the picture for tuning a grasp, or for comparing two grippers or two runs.

matplotlib is an optional dependency (``pip install 'grippers[plot]'``), imported inside :func:`run` only.
Any file that is not a recording, however malformed, ends in one line and exit code 2: :func:`load` checks
every row before anything is drawn; a file cut short (a crash, a full disk) is drawn up to its last complete
row, and plot says so. A quantity no curve reports (the MSG's speed) is a panel that says "not reported",
not an empty one. Commands that start at (nearly) the same moment share one label, so their names never
print over each other. SVG keeps its text as text (searchable, selectable).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .output import EXIT_OK, UsageError, write_json

HELP = (
    "plot recordings (grippers record) to PNG or SVG: width, speed, force or current of every gripper on one "
    "time axis, commands marked"
)
EXAMPLE = "grippers plot grasp.csv -o grasp.png\n         grippers plot left.csv right.mcap -o both.svg"
QUANTITIES = {
    "width_mm": "width (mm)",
    "speed_mm_s": "speed (mm/s)",
    "force_n": "force (N)",
    "current_a": "current (A)",
}
COLORS = ("tab:blue", "tab:orange", "tab:purple", "tab:brown", "tab:pink", "tab:olive", "tab:cyan")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "recordings", nargs="+", metavar="FILE", help="recordings: FILE.csv, FILE.jsonl or FILE.mcap"
    )
    parser.add_argument("-o", "--output", required=True, metavar="IMAGE", help="IMAGE.png or IMAGE.svg")
    parser.add_argument("--title", help="the picture's title (default: the recorded URLs)")
    parser.add_argument("--json", action="store_true", help="print what was drawn as JSON (docs/cli.md)")


@dataclass
class Series:
    """One gripper of one recording: its state rows, on the common time axis."""

    label: str
    rows: list[dict[str, Any]]

    def xy(self, key: str) -> tuple[list[float], list[float]]:
        xs, ys = [], []
        for row in self.rows:
            if row.get(key) is not None:
                xs.append(float(row["t_s"]))
                ys.append(float(row[key]))
        return xs, ys

    def reports(self, key: str) -> bool:
        return any(row.get(key) is not None for row in self.rows)


def _shifted(rows: list[dict[str, Any]], offset: float) -> list[dict[str, Any]]:
    return [{**row, "t_s": row["t_s"] + offset} for row in rows] if offset else rows


def collect(recordings: list[Any]) -> tuple[list[Series], list[dict[str, Any]]]:
    """The curves and the command rows of every recording, on one time axis: each file's times are moved by
    its start (``start_unix``) after the earliest one, so two files recorded side by side line up."""
    starts = [r.header.get("start_unix") for r in recordings]
    aligned = all(isinstance(s, int | float) for s in starts)
    first = min(starts) if aligned and starts else 0.0
    several_files = len(recordings) > 1
    names = {name for r in recordings for name in r.grippers}
    series: list[Series] = []
    commands: list[dict[str, Any]] = []
    for rec, start in zip(recordings, starts, strict=True):
        offset = float(start) - float(first) if aligned else 0.0
        rows = _shifted(rec.rows, offset)
        for name in rec.grippers:
            states = [r for r in rows if r["kind"] == "state" and r["gripper"] == name]
            if not states:
                continue
            label = name if not several_files else f"{Path(rec.path).name}: {name}"
            if several_files and names == {"gripper"}:
                label = Path(rec.path).name
            series.append(Series(label, states))
        for row in rows:
            if row["kind"] == "command":
                who = row.get("gripper")
                prefix = f"{who}: " if who and len(series) > 1 and who != "gripper" else ""
                commands.append({**row, "label": prefix + str(row.get("command"))})
    return series, commands


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


def panels_of(series: list[Series]) -> list[str]:
    """Width and speed always (a quantity no curve reports says so in its panel), then force and current
    where some curve reports them, and force when none reports either."""
    keys = ["width_mm", "speed_mm_s"]
    keys += [k for k in ("force_n", "current_a") if any(s.reports(k) for s in series)]
    return keys if len(keys) > 2 else [*keys, "force_n"]


def run(args: argparse.Namespace) -> int:
    from grippers.recording import RecordingError, load

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
        recordings = [load(path) for path in args.recordings]
    except RecordingError as exc:
        raise UsageError(str(exc)) from None
    series, commands = collect(recordings)
    if not series:
        cuts = "".join(f" ({rec.path}: cut short: {rec.cut})" for rec in recordings if rec.cut)
        raise UsageError(f"{', '.join(args.recordings)}: no states recorded{cuts}")
    for rec in recordings:
        if rec.cut is not None:  # drawn, and said: the picture is of the complete part only
            kept = sum(1 for row in rec.rows if row["kind"] == "state")
            print(
                f"grippers plot: {rec.path}: cut short ({rec.cut}): drew its {kept} complete states",
                file=sys.stderr,
            )
    keys = panels_of(series)
    fig, axes = plt.subplots(
        len(keys), 1, sharex=True, figsize=(10, 7 if len(keys) <= 3 else 9), constrained_layout=True
    )
    style = {"start": ("tab:green", "--"), "done": ("tab:gray", ":"), "failed": ("tab:red", "-")}
    for ax, key in zip(axes, keys, strict=True):
        ax.set_ylabel(QUANTITIES[key])
        ax.grid(True, alpha=0.3)
        silent = [s.label for s in series if not s.reports(key)]
        for number, s in enumerate(series):
            xs, ys = s.xy(key)
            if xs:
                ax.plot(xs, ys, color=COLORS[number % len(COLORS)], linewidth=1.5, label=s.label)
        if len(silent) == len(series):
            ax.text(0.5, 0.5, "not reported", transform=ax.transAxes, ha="center", va="center", color="0.4")
            ax.set_yticks([])
        elif silent:
            note = f"not reported: {', '.join(silent)}"
            ax.text(0.01, 0.95, note, transform=ax.transAxes, ha="left", va="top", fontsize=8, color="0.4")
        for row in commands:
            color, line = style.get(str(row.get("phase")), ("tab:gray", ":"))
            ax.axvline(float(row["t_s"]), color=color, linestyle=line, linewidth=1)
    if len(series) > 1:
        axes[0].legend(loc="lower right", fontsize=8)
    starts = [
        (float(row["t_s"]), row["label"] + (" (failed)" if row.get("phase") == "failed" else ""))
        for row in commands
        if row.get("phase") in ("start", "failed")
    ]
    times = [float(row["t_s"]) for s in series for row in s.rows] + [t for t, _ in starts]
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
    targets = [str(rec.header.get("target", rec.path)) for rec in recordings]
    fig.suptitle(args.title or " | ".join(targets))
    try:
        fig.savefig(args.output, dpi=100)
    except OSError as exc:
        raise UsageError(f"{args.output}: cannot write: {exc.strerror or exc}") from None
    except (ValueError, OverflowError) as exc:  # numbers matplotlib cannot place (finite, but 1e308 wide)
        names = ", ".join(args.recordings)
        raise UsageError(f"{names}: cannot be drawn: {' '.join(str(exc).split())[:200]}") from None
    finally:
        plt.close(fig)
    if getattr(args, "json", False):
        write_json(
            {
                "schema": "grippers.plot/1",
                "recording": " ".join(args.recordings),
                "output": args.output,
                "states": sum(len(s.rows) for s in series),
                "commands": len(commands),
                "recordings": [
                    {
                        "recording": rec.path,
                        "grippers": rec.grippers,
                        "states": sum(1 for row in rec.rows if row["kind"] == "state"),
                        "cut": rec.cut,
                    }
                    for rec in recordings
                ],
            }
        )
    else:
        print(f"wrote {args.output}")
    return EXIT_OK
