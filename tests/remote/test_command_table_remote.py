"""Every verb grippers/commands.py says is served, end to end: a ``zenoh://`` client calls the Gripper
method, the server's dispatch (derived from the same table) calls it on a served WSG 50 simulator.

tests/test_command_table.py checks the client's side without a network; this one shows the verbs the table
serves are the ones a real ``grippers serve`` answers, with the arguments the client sends.
"""

from __future__ import annotations

from collections.abc import Callable

import pytest

import grippers
from grippers import commands

from .conftest import ServeProcess, sim

pytestmark = pytest.mark.timeout(60)

SAMPLE = {"width": 0.03, "min_width": 0.005, "max_width": 0.1, "tag": "cell-3"}


def test_every_served_verb_is_answered(serve: Callable[..., ServeProcess]) -> None:
    server = serve(f"wsg={sim('wsg50', part_width_mm=30.0)}")
    verbs = commands.served()
    with grippers.open(server.urls["wsg"]) as g:
        done = []
        for verb, c in verbs.items():  # table order: home first, fast_stop before acknowledge
            kwargs = {p.name: SAMPLE[p.name] for p in c.params if p.required}
            getattr(g, c.name)(**kwargs)
            if c.name == "servo":
                g.stop()  # servoing ends; the next verb is not queued behind it
            done.append(verb)
        assert done == list(verbs)
        assert g.device_tag() == "cell-3"
