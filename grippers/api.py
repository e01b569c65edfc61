"""``grippers.open``: a URL, a profile name or a profile file in, a ready :class:`Gripper` out."""

from __future__ import annotations

import logging
import os
import warnings
from typing import Any

from .backends import get_backend
from .errors import GripperError, ProfileAssumed, ProfileError, URLError
from .gripper import Gripper
from .profiles import PROFILE_SUFFIXES, ProfileBase, load_profile
from .settings import Settings
from .timeouts import SIM_MIN_TIMEOUT_S
from .urls import ConnectionURL, is_url, parse_url

DEFAULT_SIM_PROFILE = "wsg50"
log = logging.getLogger(__name__)


def open(target: str | os.PathLike[str], **overrides: Any) -> Gripper:  # noqa: A001 - the public name
    """Open a gripper; use it as a context manager so it is closed (and a TCP WSG is not left in FAST STOP).

    ``target`` is a connection URL (``wsg+tcp://192.168.1.20``, ``stepfoc+can://socketcan/can0?node=0``,
    ``sim://msg-150?part_width_mm=40``), a profile name (``wsg50``; connects to the profile's ``url``) or a
    profile file. Keyword overrides win over URL query parameters, which win over profile fields;
    ``profile=`` names the profile when the device cannot report its model (the MSG's rail length).

    Raises:
        URLError: the URL does not follow the grammar, or a setting is unknown or invalid.
        ProfileError: no such profile, a profile that does not validate, or one of another family.
        GripperTimeout: nothing answered within the timeout (a wrong address, node id or baud rate).
        ConnectionLost: the transport could not be opened or closed at once (port, bus, refused TCP).
        ProtocolError: something answered, but not as a gripper of this family would.

    Warns:
        ProfileAssumed: the device cannot report its model and no profile was named (an MSG: taken as
            msg-150); widths are wrong on another model.
    """
    text = os.fspath(target)
    chosen = overrides.pop("profile", None)  # a name or a loaded profile; the keyword wins over ?profile=
    profile: ProfileBase | None = None
    if is_url(text):
        url = _parse(text)
    else:
        _refuse_bare_port(text)
        profile = load_profile(text)
        url = _parse(overrides.pop("url", None) or profile.url)
    settings = Settings(url.url, url.params, overrides)
    from .reconnect import SETTINGS as RECONNECT_SETTINGS

    settings.expect(*RECONNECT_SETTINGS)  # taken once the gripper is open (_finish), known before it connects
    from_query = settings.str("profile", None)
    if chosen is None:
        chosen = from_query
    if isinstance(chosen, ProfileBase):
        profile = chosen
    elif chosen is not None:
        profile = load_profile(chosen)
    if url.family == "sim":
        return _open_sim(url, profile, settings)
    if getattr(target, "simulator", None) is not None:  # grippers.testing.SimURL: served in this process
        settings.at_least("timeout", SIM_MIN_TIMEOUT_S)
    backend = get_backend(url.family)
    if profile is not None and profile.family != url.family:
        raise ProfileError(
            f"{url.url}: profile {profile.name!r} is for family {profile.family!r}, not {url.family!r}"
        )
    gripper = backend.open(url, profile, settings)
    _finish(gripper, settings)
    warn_if_assumed(gripper)
    return gripper


def _refuse_bare_port(text: str) -> None:
    """A serial port given where a URL goes (``/dev/ttyUSB0``): the next step in the user's terms, not
    "profile file not found" (issue 39 §2). Every family talks over a serial port, so only the user can say
    which one is plugged in; ``grippers probe`` asks the port."""
    if text.startswith("/dev/") and not text.lower().endswith(PROFILE_SUFFIXES):
        raise URLError(
            f"{text}: a serial port is opened through its family's URL, FAMILY+serial://{text}; "
            f"`grippers probe serial://{text}` finds which family answers there"
        )


def _parse(text: str) -> ConnectionURL:
    """:func:`grippers.urls.parse_url`: the grammar, with a family's own schemes (``robotiq+urcap://``,
    ``schunk+http://``)."""
    return parse_url(text)


def warn_if_assumed(gripper: Gripper, stacklevel: int = 3) -> None:
    """Issue :class:`ProfileAssumed` when the backend guessed the model (issue 22 §1: no silent assumption).

    Said at open, not only in ``info()``: an MSG 100 taken for an MSG 150 reads 105 mm with the jaws at 55 mm,
    and a user who never calls ``info()`` would not know. ``stacklevel`` points at the caller of ``open()``.
    """
    if getattr(gripper, "_profile_assumed", False):
        warnings.warn(
            ProfileAssumed(
                f"model {gripper.profile.name} assumed (the device cannot report its model or stroke: "
                "on another model every width is wrong); pass profile= (--profile)"
            ),
            stacklevel=stacklevel,
        )


def _finish(gripper: Gripper, settings: Settings) -> None:
    try:
        from .reconnect import attach

        attach(gripper, settings)  # reconnect=true and its settings (grippers/reconnect.py)
        settings.finish()
    except Exception:
        gripper.close()
        raise
    log.info("%s: opened (profile %s)", gripper.url, gripper.profile.name)


def _open_sim(url: ConnectionURL, profile: ProfileBase | None, settings: Settings) -> Gripper:
    """An in-process simulator served over a real transport (loopback TCP, a pty, a virtual CAN bus), and
    the ordinary backend connected to it: ``sim://`` exercises the same code as hardware."""
    if url.profile:
        named = load_profile(url.profile)
        if profile is not None and profile.name != named.name:
            # Two different models asked for: simulating either one silently would test the wrong gripper.
            raise ProfileError(f"{url.url}: simulates {named.name!r}, but profile {profile.name!r} was given")
        profile = named
    elif profile is None:
        profile = load_profile(DEFAULT_SIM_PROFILE)
    backend = get_backend(profile.family)
    if not hasattr(backend, "simulator"):
        raise ProfileError(f"{url.url}: the {profile.family!r} backend has no simulator")
    try:
        server = backend.simulator(profile, settings)
    except ValueError as exc:
        if isinstance(exc, GripperError):
            raise
        # Every simulator parameter comes from the URL or the keywords, so a refused one is a settings error.
        raise URLError(f"{url.url}: {exc}") from exc
    try:
        sim_url = _parse(server.url)
        settings.add_defaults(sim_url.params)  # e.g. the UDP simulator's reply port
        settings.at_least("timeout", SIM_MIN_TIMEOUT_S)  # it shares this process's CPU: grippers.timeouts
        gripper = backend.open(sim_url, profile, settings)
    except BaseException:
        server.close()
        raise
    gripper.simulator = server  # tests and demos reach the model and its fault hooks here
    gripper._on_close.append(server.close)
    _finish(gripper, settings)
    return gripper
