"""The JSON documents' grasp-state names are GraspState's values, one for one."""

from __future__ import annotations

from typing import get_args

from grippers.states import GraspName, GraspState


def test_grasp_names_are_the_enum_values() -> None:
    assert set(get_args(GraspName)) == {state.value for state in GraspState}
