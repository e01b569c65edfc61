"""One gripper behind the panel: its live snapshot, the page in control, the commands pages send.

The gripper is any :class:`~grippers.Gripper` (every family, ``zenoh://`` too): the session only calls the
vendor-neutral API, so limits, refusals and their messages are the library's own. Commands come in page
units (mm, mm/s, N) and are converted to SI here; nothing else reaches the gripper. Motions start without
waiting (``wait=False``): the page gets its reply at once and the outcome when the motion ends, and a stop
from any page is never queued behind a motion.

The deadman: a page that controlled the gripper and goes away (closed, or its connection lost: the server's
WebSocket pings notice within ``PING_TIMEOUT_S``) while the jaws move has them stopped, as the remote lease's
deadman does for a vanished ``zenoh://`` holder.
"""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..cli.output import info_dict, limits_dict, state_dict
from ..errors import GripperError, LimitError
from ..gripper import Capability, Gripper, GripperState
from ..units import to_m
from .control import Control, Page
from .recording import PanelRecording

log = logging.getLogger("grippers.panel")

# Arguments of each command (page units), all optional numbers: anything else is refused before the gripper.
ARGS = {
    "home": (),
    "move": ("width_mm", "speed_mm_s"),
    "jog": ("delta_mm", "speed_mm_s"),
    "grasp": ("width_mm", "force_n", "speed_mm_s"),
    "release": ("speed_mm_s",),
    "stop": (),
    "fast_stop": (),
    "acknowledge": (),
    "take_control": (),
    "record": ("on",),
}
MOTIONS = frozenset({"home", "move", "jog", "grasp", "release"})
TEMPERATURE_EVERY = 50  # states (2 s at 25 Hz): a temperature changes slowly and costs an exchange

Tell = Callable[[str, dict[str, Any]], None]  # (page id, message): a message for one page


def error_dict(exc: BaseException) -> dict[str, Any]:
    """A refused or failed command as the page shows it: the library's class and message, no traceback."""
    if isinstance(exc, GripperError):
        said = exc.command and not exc.message.startswith(exc.command)  # "move refused: …" names it already
        text = f"{exc.command}: {exc.message}" if said else exc.message
    else:
        log.exception("panel: unexpected error")
        text = f"internal error: {type(exc).__name__}: {exc}"
    return {"ok": False, "error": type(exc).__name__, "message": " ".join(text.split())}


class GripperSession:
    """A gripper as the panel shows and drives it."""

    def __init__(self, name: str, gripper: Gripper, *, tell: Tell, workdir: Path) -> None:
        self.name = name
        self.gripper = gripper
        self.control = Control(gripper.name)
        self.remote = hasattr(gripper, "acquire_control")  # a zenoh:// gripper: the server's lease too
        self._tell = tell
        self._recording = PanelRecording(name, gripper, workdir)
        self._lock = threading.Lock()
        self._motion: Any = None  # the handle of the last motion a page started
        self.seq = 0
        self.info_seq = 0  # bumped when the identity or the limits change (read again after a reconnection)
        self.state: dict[str, Any] | None = None
        self.moving = False
        self.info: dict[str, Any] | None = None
        self.temperature: float | None = None  # °C, where the device reports it
        self._states = 0
        self.connected = gripper.connected
        self.lost: str | None = None
        self._stream: Any = None
        self._unlisten = gripper.on_connection(self._on_connection)
        self._read_info()
        self._open_stream()

    # -- what the pages see ------------------------------------------------------------------------------

    def snapshot(self, identity: bool = True) -> dict[str, Any]:
        """What a page shows; ``identity=False`` leaves out what changes only with ``info_seq`` (the info, the
        limits), which a page already has."""
        holder = self.control.holder
        fixed = {
            "url": self.gripper.url,
            "remote": self.remote,
            "info": self.info,
            "limits": limits_dict(self.gripper.limits),
        }
        return {
            "name": self.name,
            "seq": self.seq,
            "info_seq": self.info_seq,
            **(fixed if identity else {}),
            "connected": self.connected,
            "lost": self.lost,
            "state": self.state,
            "temperature_c": self.temperature,
            "controller": None if holder is None else {"id": holder.id, "label": holder.label},
            "recording": self._recording.running,
            "downloads": self._recording.downloads,
        }

    def _bump(self) -> None:
        with self._lock:  # the pages' senders send a snapshot whose seq they have not sent yet
            self.seq += 1

    def _on_state(self, st: GripperState) -> None:
        self.moving = st.moving
        self.state = {**state_dict(st), "t": st.timestamp}
        if self._states % TEMPERATURE_EVERY == 0 and Capability.TEMPERATURE in self.gripper.capabilities:
            # not on this thread: a zenoh:// gripper calls back from Zenoh's, where a query must not wait
            threading.Thread(target=self._read_temperature, name="grippers-panel-temp", daemon=True).start()
        self._states += 1
        self._bump()

    def _read_temperature(self) -> None:
        try:
            self.temperature = round(self.gripper.temperature(), 1)
        except GripperError:
            self.temperature = None

    def _open_stream(self, rate_hz: float = 25.0) -> None:
        try:
            self._stream = self.gripper.stream(rate_hz, callback=self._on_state)
        except GripperError as exc:
            self.lost = error_dict(exc)["message"]

    def _read_info(self) -> None:
        try:
            self.info = info_dict(self.gripper.info())
            with self._lock:
                self.info_seq += 1
        except GripperError as exc:
            self.lost = error_dict(exc)["message"]

    def _on_connection(self, up: bool) -> None:
        self.connected = up
        if up:
            self.lost = None
            threading.Thread(target=self._back, name="grippers-panel-info", daemon=True).start()
        else:
            error = getattr(getattr(self.gripper, "link_watch", None), "last_error", None)
            self.lost = f"connection lost{': ' + str(error) if error else ''}"
        self._bump()

    def _back(self) -> None:
        self._read_info()
        self._bump()

    # -- commands ------------------------------------------------------------------------------------------

    def run(self, page: Page, command: str, args: dict[str, Any]) -> dict[str, Any]:
        """Carry out ``command`` for ``page`` (a worker thread: it may block on the device); the reply."""
        try:
            return self._run(page, command, args)
        except Exception as exc:
            return error_dict(exc)

    def _run(self, page: Page, command: str, args: dict[str, Any]) -> dict[str, Any]:
        values = self._values(command, args)
        if command == "take_control" and self.remote:
            self.gripper.acquire_control()  # type: ignore[attr-defined]  # AccessDenied: another client's
        if self.control.admit(page, command):
            self._bump()
        g = self.gripper
        if command in MOTIONS:
            handle = self._start(command, values)
            self._motion = handle
            handle.add_done_callback(lambda h: self._ended(page, command, h))
            return {"ok": True, "started": True}
        if command == "stop":
            g.stop()
        elif command == "fast_stop":
            g.fast_stop()
        elif command == "acknowledge":
            g.acknowledge()
        elif command == "record":
            if values["on"]:
                self._recording.start()
            else:
                self._recording.stop()
            self._bump()
        return {"ok": True}

    def _values(self, command: str, args: dict[str, Any]) -> dict[str, Any]:
        known = ARGS.get(command)
        if known is None:
            raise GripperError(f"no such command {command!r}", device=self.gripper.name, command=command)
        out: dict[str, Any] = {}
        for key, value in args.items():
            if key not in known:
                raise LimitError(f"unknown argument {key!r}", device=self.gripper.name, command=command)
            if key == "on":
                if not isinstance(value, bool):
                    raise LimitError("on: true or false", device=self.gripper.name, command=command)
            elif value is not None and (
                isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value)
            ):
                raise LimitError(f"{key}: not a number", device=self.gripper.name, command=command)
            out[key] = value
        return out

    def _start(self, command: str, v: dict[str, Any]) -> Any:
        g, speed = self.gripper, to_m(v.get("speed_mm_s"))
        if command == "home":
            return g.home(wait=False)
        if command == "move":
            if v.get("width_mm") is None:
                raise LimitError("give a width", device=g.name, command="move")
            return g.move(to_m(v["width_mm"]), speed, wait=False)
        if command == "jog":
            delta = v.get("delta_mm")
            if delta is None:
                raise LimitError("give a distance", device=g.name, command="jog")
            return g.move(g.state().width + to_m(delta), speed, wait=False)
        if command == "grasp":
            if v.get("width_mm") is None:
                raise LimitError("give the part's width", device=g.name, command="grasp")
            return g.grasp(to_m(v["width_mm"]), speed, v.get("force_n"), wait=False)
        return g.release(None, speed, wait=False)

    def _ended(self, page: Page, command: str, handle: Any) -> None:
        try:
            handle.wait(0)
            outcome: dict[str, Any] = {"ok": True}
        except BaseException as exc:
            outcome = error_dict(exc)
        self._tell(page.id, {"type": "done", "name": self.name, "command": command, **outcome})

    # -- pages coming and going --------------------------------------------------------------------------

    def page_left(self, page: Page) -> None:
        """The deadman: the controlling page is gone; what it set moving stops, a served lease is freed."""
        if not self.control.leave(page):
            return
        motion = self._motion
        if (motion is not None and not motion.done()) or self.moving:
            log.warning(
                "%s: the controlling page (%s) left while the jaws moved: stopping", self.name, page.label
            )
            try:
                self.gripper.stop()
            except GripperError as exc:
                log.warning("%s: stop after the page left failed: %s", self.name, exc)
        if self.remote:
            try:
                self.gripper.release_control()  # type: ignore[attr-defined]
            except GripperError:
                pass
        self._bump()

    def download(self, fmt: str) -> Path | None:
        return self._recording.file(fmt)

    def close(self) -> None:
        """Stop the recording and the stream; the gripper is its opener's to close."""
        self._unlisten()
        if self._stream is not None:
            self._stream.close()
        self._recording.close()
