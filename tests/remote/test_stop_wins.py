"""Issue 43 §9 (high): over ``zenoh://``, a stop from another client wins over everything the server received
before it. Before: 3,000 servo targets of the holder, then another client's ``stop()`` 0.1 s later: the jaws
stopped at 28-31 mm, then went on to the last target (3 runs in 3): the holder's requests waited on the
ordinary pool while the stop ran at once on the urgent one."""

from __future__ import annotations

import time

import pytest

import grippers

from .conftest import ServeProcess

pytestmark = pytest.mark.timeout(120)


def test_a_stop_from_another_client_is_not_undone_by_targets_received_before_it(serve, gripper_sim) -> None:
    device = gripper_sim("wsg50", time_scale=1)
    server: ServeProcess = serve(f"g={device}")
    holder, other = grippers.open(server.urls["g"]), grippers.open(server.urls["g"])
    last = 0.010
    try:
        holder.home()
        holder.acquire_control()
        start = holder.state().width
        # 3,000 targets sent at once on the holder's own session with its lease, as a program that does not
        # wait for each answer sends them: the server receives them faster than its pool answers them, so
        # most still wait there when the stop arrives. (The zenoh:// client sends one at a time; the server
        # must hold for any client.)
        link = holder.device._link
        key = "grippers/g/cmd/servo"
        pending = [
            link.session.get(
                key,
                payload=link.holder.request(
                    {"width": start - (start - last) * (i + 1) / 3000, "speed": 0.02, "force": None}
                ),
                timeout=30,
            )
            for i in range(3000)
        ]
        time.sleep(0.1)
        other.stop()
        refused = 0
        for handler in pending:
            for reply in handler:
                refused += reply.err is not None
        time.sleep(1.0)  # whatever was queued has been answered by now
        with grippers.open(device) as direct:
            first = direct.state()
            time.sleep(1.0)
            later = direct.state()
        assert not later.moving, later
        assert later.width == pytest.approx(first.width, abs=2e-4), (first.width, later.width)
        assert later.width > last + 0.02, later.width  # far from the last target: the stop held
        assert refused > 0  # targets answered after the stop were refused
    finally:
        holder.close()
        other.close()


def test_a_servoing_client_stopped_by_another_begins_anew_only_when_it_says_so(serve, gripper_sim) -> None:
    """The zenoh:// client's own path: its servo loop sends the latest target after another client's stop;
    the server refuses it (the jaws stay), the holder is told, and stop() then servo() begin anew."""
    device = gripper_sim("wsg50", time_scale=1)
    server: ServeProcess = serve(f"g={device}")
    holder, other = grippers.open(server.urls["g"]), grippers.open(server.urls["g"])
    try:
        holder.home()
        start = holder.state().width
        holder.servo(start - 0.01, 0.02)
        holder.servo_flush(10)
        other.stop()
        with pytest.raises(grippers.CommandFailed, match="another client's stop"):
            deadline = time.monotonic() + 10
            while time.monotonic() < deadline:  # targets sent after the stop, from the same servoing
                holder.servo(0.010, 0.02)
                holder.servo_flush(10)
        with grippers.open(device) as direct:
            first = direct.state()
            time.sleep(0.5)
            assert not direct.state().moving and direct.state().width == pytest.approx(first.width, abs=2e-4)
        holder.stop()  # ends the servoing here too
        holder.servo(first.width - 0.005, 0.02)  # a new servoing: accepted
        holder.servo_flush(10)
        deadline = time.monotonic() + 10
        while abs(holder.state().width - (first.width - 0.005)) > 5e-4:
            assert time.monotonic() < deadline, holder.state()
            time.sleep(0.05)
    finally:
        holder.close()
        other.close()
