"""``grippers selftest URL``: a bench acceptance run, to learn whether the profile fits this unit before a
robot relies on it.

It homes twice (the second is the recalibration of a calibrated MSG, the case that hides timing bugs), moves
over the middle of the stroke at three speeds, closes once without a part at the lowest force, and reads back
the faults and the fault-related settings; then prints measured against expected with PASS, WARN or INFO per
line. Nothing in it needs a part or goes near the end stops at speed: it is safe on a bench with empty jaws,
and it says so and asks before the first motion (``--yes`` for scripts).

Everything goes through the :class:`~grippers.gripper.Gripper` API (and the vendor extras behind
``gripper.driver`` for the read-backs only): no protocol code here. The arithmetic is in
:mod:`grippers.cli.selftest_checks`.

Exit codes: 0 every line PASS (or INFO); 3 the run finished with at least one WARN (the profile does not fit:
``--write-profile`` writes one that does); 1 the device failed a step; 2 a usage error or not confirmed;
130 interrupted (the jaws are stopped first: the timed moves run with ``wait=False`` while the state is
polled, so the command stops them itself, :func:`~grippers.cli.common.stops_motions_on_error`).
"""

from __future__ import annotations

import argparse
import sys
import time
from typing import TYPE_CHECKING, Any

from .common import add_common, add_target, opened_gripper
from .output import EXIT_OK, UsageError, m_to_mm, mm_to_m, table, write_json

if TYPE_CHECKING:
    from .selftest_target import ProfileTarget

HELP = "bench acceptance run: homes, moves at three speeds, closes without a part; measured vs the profile"
EXAMPLE = (
    "grippers selftest 'sim://?time_scale=20' --yes\n"
    "         grippers selftest FAMILY+tcp://192.168.1.20   (your gripper's URL)\n"
    "         grippers selftest 'FAMILY+can://socketcan/can0?node=0' --profile PROFILE --yes --json\n"
    "         grippers selftest 'FAMILY+can://socketcan/can0?node=0' --write-profile my-gripper.toml"
)

SELFTEST_SCHEMA_ID = "grippers.selftest/1"
EXIT_WARN = 3  # finished, and at least one line is a WARN (docs/cli.md)
SPEED_FRACTIONS = (0.2, 0.45, 0.7)  # of the profile's top speed: slow, middle, fast, none at the limit
SPAN = (0.2, 0.8)  # of the stroke: the safe span, away from both end stops
DEFAULT_TOLERANCE = 0.15
MAX_TOLERANCE = 1.0  # ±100 %: beyond it every speed passes, and the run says nothing
POSITION_TOLERANCE = 0.02  # of the stroke: where a move ended against its target


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_target(parser)
    parser.add_argument("-y", "--yes", action="store_true", help="do not ask before moving (for scripts)")
    parser.add_argument(
        "--write-profile",
        metavar="FILE",
        help="write a TOML profile that extends the base profile with the measured values",
    )
    parser.add_argument(
        "--profile-name", metavar="NAME", help="the written profile's name (default: BASE-measured)"
    )
    parser.add_argument(
        "--force",
        action="store_true",
        help="with --write-profile: replace FILE if it exists (it is replaced whole, after the run)",
    )
    parser.add_argument(
        "--tolerance",
        type=tolerance,
        default=DEFAULT_TOLERANCE,
        metavar="FRACTION",
        help=f"relative deviation accepted on top of the measurement's own uncertainty, at most "
        f"{MAX_TOLERANCE:g} (default {DEFAULT_TOLERANCE:g})",
    )
    parser.add_argument(
        "--time-scale",
        type=time_scale,
        metavar="N",
        help="a simulator running N times faster than real time (default: a sim:// URL's time_scale, else 1)",
    )
    add_common(parser)


def _bounded(text: str, name: str, low: float, high: float) -> float:
    """An argparse type: a finite number within [low, high], checked by the library's one number rule."""
    from grippers.drivers.numbers import finite
    from grippers.errors import LimitError

    try:
        number = float(text)  # text is parsed here: the library's rule takes numbers, not strings
    except ValueError:
        raise argparse.ArgumentTypeError(f"{name} must be a number, not {text!r}") from None
    try:
        return finite(number, name, low=low, high=high)
    except LimitError as exc:
        raise argparse.ArgumentTypeError(exc.message) from None


def time_scale(text: str) -> float:
    """``--time-scale``: the simulators' own range (grippers/profiles.py ``TimeScale``), so an absurd scale
    (1e308 ended in an errno tuple after homing and moving, issue 33 §3) is a usage error before anything
    moves."""
    from grippers.profiles import MAX_TIME_SCALE

    return _bounded(text, "time scale", 1 / MAX_TIME_SCALE, MAX_TIME_SCALE)


def tolerance(text: str) -> float:
    value = _bounded(text, "tolerance", 0.0, MAX_TOLERANCE)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"tolerance must be above 0, not {text!r}")
    return value


def _time_scale(args: argparse.Namespace) -> float:
    if args.time_scale is not None:
        return float(args.time_scale)
    from grippers.urls import URLError, parse_url, to_float

    try:
        target = parse_url(args.target)
        if target.family == "sim" and "time_scale" in target.params:
            return to_float(target.params["time_scale"], "time_scale", args.target)
    except URLError:
        pass  # refused with the grammar's own message when the gripper opens (a time_scale out of range too)
    return 1.0


def plan_text(name: str, lo_mm: float, hi_mm: float, speeds: list[float], force: float) -> str:
    return (
        f"grippers selftest will move {name}:\n"
        f"  home twice (the gripper references itself; some calibrate: the jaws travel to both end stops);\n"
        f"  move between {lo_mm:.1f} and {hi_mm:.1f} mm at {', '.join(f'{s:g}' for s in speeds)} mm/s;\n"
        f"  close from {hi_mm:.1f} mm as for a part of {lo_mm:.1f} mm at {force:g} N (keep the jaws EMPTY);\n"
        f"  open again, and read the faults and settings back."
    )


def _confirm(plan: str, yes: bool) -> None:
    print(plan, file=sys.stderr)
    if yes:
        return
    answer = input("go ahead? [y/N] ").strip().lower()
    if answer not in ("y", "yes"):
        raise UsageError("not confirmed; nothing moved")


def _timed_move(
    gripper: Any, target: float, speed: float
) -> tuple[list[tuple[float, float]], list[float | None], float, float]:
    """Samples (wall s, mm) of one move while it runs, the speeds the device reported with them (mm/s, None
    where it reports none), the move's wall duration and the mean poll interval."""
    samples: list[tuple[float, float]] = []
    reported: list[float | None] = []
    start = time.monotonic()
    handle = gripper.move(target, speed, wait=False)
    while not handle.done():
        state = gripper.state()
        samples.append((time.monotonic(), m_to_mm(state.width)))
        reported.append(m_to_mm(state.speed))
    handle.wait()
    end = time.monotonic()
    duration = end - start
    poll = duration / max(len(samples), 1)
    return [(t - start, w) for t, w in samples], reported, duration, poll


def _accel(gripper: Any) -> float | None:
    """The acceleration the device ramps with (mm/s²), where it says (WSG 31h); None elsewhere."""
    read = getattr(gripper.driver, "acceleration", None)
    if read is None:
        return None
    try:
        return float(read())
    except Exception:  # a device that cannot say: the speeds are then fractions of the profile's top
        return None


class _Run:
    """The steps of one selftest, collecting lines; each step is one method."""

    def __init__(self, gripper: Any, scale: float, tolerance: float) -> None:
        from .selftest_checks import Line, SpeedMeasurement, test_speeds

        self.g = gripper
        self.scale = scale
        self.tolerance = tolerance
        self.lines: list[Line] = []
        self.speeds: list[SpeedMeasurement] = []
        self.stroke_mm: float | None = None
        limits = gripper.limits
        self.lo_mm = m_to_mm(limits.min_width + SPAN[0] * limits.stroke)
        self.hi_mm = m_to_mm(limits.min_width + SPAN[1] * limits.stroke)
        self.speed_list = test_speeds(
            m_to_mm(limits.min_speed),
            m_to_mm(limits.max_speed),
            self.hi_mm - self.lo_mm,
            SPEED_FRACTIONS,
            _accel(gripper),
        )
        self.force = limits.min_force

    def add(self, *args: Any, **kwargs: Any) -> None:
        from .selftest_checks import Line

        self.lines.append(Line(*args, **kwargs))

    def device_s(self, wall: float) -> float:
        return wall * self.scale

    def faults(self, when: str) -> None:
        st = self.g.state()
        if st.faults:
            self.add(
                f"faults {when}", ", ".join(st.faults), "none", "WARN", "acknowledge them (grippers ack)"
            )
        else:
            self.add(f"faults {when}", "none", "none", "PASS")

    def stroke(self) -> None:
        from grippers.backends import find_backend
        from grippers.backends.command_hooks import commands_of

        profile_mm = self.g.profile.mechanics.stroke_mm
        info = self.g.info()
        if commands_of(find_backend(info.family)).reports_stroke:
            # The device reports its own limits; the backend narrows the profile's with them.
            self.stroke_mm = m_to_mm(info.limits.stroke)
            ok = abs(self.stroke_mm - profile_mm) <= POSITION_TOLERANCE * profile_mm
            self.add(
                "stroke",
                f"{self.stroke_mm:.1f} mm",
                f"{profile_mm:g} mm",
                "PASS" if ok else "WARN",
                "" if ok else "the device reports another stroke: another model?",
                value=self.stroke_mm,
            )
        else:
            self.add(
                "stroke",
                "-",
                f"{profile_mm:g} mm",
                "INFO",
                f"the {info.family} gripper does not report its stroke: check the width at the open stop "
                "with a caliper",
            )

    def home(self, which: str) -> None:
        start = time.monotonic()
        self.g.home()
        took = self.device_s(time.monotonic() - start)
        # The library's own bound on home() (Gripper.home: twice the travel at 20 mm/s, plus slack); a unit
        # that needs more than half of it is one slow day away from a GripperTimeout.
        bound = self.device_s(self.g.async_support().motion_timeout(2 * self.g.limits.stroke, 0.02)) / 2
        ok = took <= bound
        self.add(
            f"home ({which})",
            f"{took:.2f} s",
            f"< {bound:.1f} s",
            "PASS" if ok else "WARN",
            "" if ok else "slower than half the library's wait",
            value=took,
        )
        st = self.g.state()
        self.add(
            f"referenced after home ({which})",
            "yes" if st.referenced else "no",
            "yes",
            "PASS" if st.referenced else "WARN",
        )

    def moves(self) -> None:
        from .selftest_checks import SpeedMeasurement, fit_speed, speed_verdict

        stroke_mm = m_to_mm(self.g.limits.stroke)
        self.g.move(mm_to_m(self.lo_mm))
        here, there = self.lo_mm, self.hi_mm
        for speed in self.speed_list:
            samples, reported, duration, poll = _timed_move(self.g, mm_to_m(there), mm_to_m(speed))
            end = m_to_mm(self.g.state().width)
            # Wall times to device times: a simulator N times faster than real time moves N times faster.
            dev = [(self.device_s(t), w) for t, w in samples]
            measured, uncertainty, used, method = fit_speed(
                dev, here, there, self.device_s(duration), self.device_s(poll), reported
            )
            m = SpeedMeasurement(speed, measured, uncertainty, used, method)
            self.speeds.append(m)
            self.lines.append(speed_verdict(m, self.tolerance))
            ok = abs(end - there) <= POSITION_TOLERANCE * stroke_mm
            self.add(
                f"end of move at {speed:g} mm/s",
                f"{end:.1f} mm",
                f"{there:.1f} mm ±{POSITION_TOLERANCE * stroke_mm:.1f}",
                "PASS" if ok else "WARN",
                "" if ok else "the move ended away from its target",
                value=end,
            )
            took = self.device_s(duration)
            expected = abs(there - here) / speed
            self.add(
                f"duration at {speed:g} mm/s",
                f"{took:.2f} s",
                f"{expected:.2f} s at the requested speed",
                "INFO",
                value=took,
            )
            here, there = there, here

    def close_without_part(self) -> None:
        off_mm = abs(m_to_mm(self.g.state().width) - self.hi_mm)
        if off_mm > POSITION_TOLERANCE * m_to_mm(self.g.limits.stroke):
            self.g.move(mm_to_m(self.hi_mm))
        start = time.monotonic()
        result = self.g.grasp(mm_to_m(self.lo_mm), force=self.force)
        took = self.device_s(time.monotonic() - start)
        self.add(
            "close without a part",
            "no part" if not result.grasped else f"holding at {m_to_mm(result.width):.1f} mm",
            "no part",
            "WARN" if result.grasped else "PASS",
            "reported a part in empty jaws: stall detection too eager, or the jaws are not empty"
            if result.grasped
            else "",
        )
        self.add("close duration", f"{took:.2f} s", "-", "INFO", value=took)
        self.g.release()

    def settings(self) -> None:
        """The family's own lines (its ``selftest_checks`` hook), which read its device client: they run
        whether or not the family offers device settings (issue 40), and only where the client is here."""
        from grippers.backends import find_backend
        from grippers.backends.command_hooks import commands_of

        family = self.g.info().family
        hooks = commands_of(find_backend(family))
        if not hooks.local(self.g):
            self.add(
                "settings",
                "-",
                "-",
                "INFO",
                "not served over the network: run selftest on the serving machine",
            )
            return
        if hooks.read_settings(self.g) is None:
            self.add("settings", "-", "-", "INFO", f"the {family} backend offers no device settings")
        hooks.selftest_checks(self.g, self.add)


def _document(run: _Run, args: argparse.Namespace, info: Any, written: str | None) -> dict[str, Any]:
    from dataclasses import asdict

    warn = sum(1 for ln in run.lines if ln.verdict == "WARN")
    return {
        "schema": SELFTEST_SCHEMA_ID,
        "target": args.target,
        "family": info.family,
        "profile": info.profile,
        "time_scale": run.scale,
        "tolerance": run.tolerance,
        "lines": [{k: v for k, v in asdict(ln).items()} for ln in run.lines],
        "warnings": warn,
        "ok": warn == 0,
        "written_profile": written,
    }


def _target(args: argparse.Namespace, gripper: Any) -> ProfileTarget | None:
    """``--write-profile FILE``, checked before anything moves (grippers/cli/selftest_target.py)."""
    if not args.write_profile:
        return None
    from .selftest_target import check_target

    base = gripper.profile
    return check_target(
        args.write_profile, base, args.profile_name or f"{base.name}-measured", force=args.force
    )


def _write(run: _Run, target: ProfileTarget) -> str:
    from .selftest_checks import measured_profile

    doc = measured_profile(target.base, run.lines, run.speeds, target.name, run.stroke_mm)
    return target.write(doc)


def _print_table(run: _Run) -> None:
    rows = [(ln.check, ln.measured, ln.expected, ln.verdict, ln.note) for ln in run.lines]
    print(table(rows, ("check", "measured", "expected", "verdict", "note")), flush=True)


def run(args: argparse.Namespace) -> int:
    if not args.yes and not sys.stdin.isatty():
        raise UsageError("selftest moves the gripper: add --yes to run it without a terminal to ask on")
    if args.force and not args.write_profile:
        raise UsageError("--force goes with --write-profile FILE")
    scale = _time_scale(args)
    with opened_gripper(args) as gripper:
        target = _target(args, gripper)
        info = gripper.info()
        st = _Run(gripper, scale, args.tolerance)
        _confirm(plan_text(gripper.name, st.lo_mm, st.hi_mm, st.speed_list, st.force), args.yes)
        st.faults("before")
        st.home("1st")
        st.home("2nd")
        st.stroke()
        st.moves()
        st.close_without_part()
        st.settings()
        st.faults("after")
    document = _document(st, args, info, None)
    summary = "all PASS" if document["ok"] else f"{document['warnings']} WARN"
    # The results come first, whatever becomes of the file: a run takes minutes and moves the jaws.
    if not args.json:
        _print_table(st)
    try:
        if target is not None:
            document["written_profile"] = _write(st, target)
    except BaseException:
        if args.json:
            write_json(document)
        else:
            print(f"\n{summary}; the profile was not written")
        raise
    if args.json:
        write_json(document)
    else:
        written = document["written_profile"]
        print(f"\n{summary}" + (f"; wrote {written}" if written else ""))
    return EXIT_OK if document["ok"] else EXIT_WARN
