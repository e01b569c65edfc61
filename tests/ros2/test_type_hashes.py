"""The control_msgs interfaces we build are upstream's, so a real ROS 2 system's clients talk to our node.

ROS 2 (since Iron) matches topic, service and action types by their RIHS01 type hash (REP 2011): a definition
that differs from upstream in one field makes the node invisible to a `ros2 action send_goal` of a real
installation. Two checks, each against values computed outside this repository:

* the vendored files are byte-identical to upstream: their git blob ids equal those of
  ros-controls/control_msgs at tag 5.8.0 (`git rev-parse 5.8.0:control_msgs/<file>`, or the blob SHA
  GitHub shows for the file);
* the hashes rosidl computed when scripts/setup-ros2.sh built them equal the hashes that rosbags 0.11.9
  (`Typestore.hash_rihs01` over its ROS2_JAZZY store plus the upstream definitions) computes independently.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import pytest

from .conftest import SKIP_REASON

VENDORED = Path(__file__).resolve().parents[2] / "scripts" / "ros2" / "control_msgs"

UPSTREAM_BLOBS = {  # ros-controls/control_msgs, tag 5.8.0 (commit f901df2662f22a39a06aa04a85a34602c47e3cc0)
    "msg/GripperCommand.msg": "bf137a3071fd67c2f52e65a90613f4fed2c148bf",
    "action/GripperCommand.action": "171f7d09c5ef75a6df69895324372e387ca463f2",
    "action/ParallelGripperCommand.action": "90405b9a10f21e05c35f0983ef9e7b0c52d5f0fd",
}

# rosbags 0.11.9: get_typestore(Stores.ROS2_JAZZY), the upstream 5.8.0 definitions registered with
# get_types_from_msg (an action split at its "---" lines into _Goal, _Result, _Feedback), then
# hash_rihs01(name).
RIHS01 = {
    "control_msgs/msg/GripperCommand": (
        "RIHS01_57eb8f326c9889ca8bb34ead82cc94cc09bf6bc5c3b6c09546dca3a00b589890"
    ),
    "control_msgs/action/GripperCommand_Goal": (
        "RIHS01_607d9f41eb241e1922e90f02125e87ae6bfb78f7f64a71dc92630263d01f8b6d"
    ),
    "control_msgs/action/GripperCommand_Result": (
        "RIHS01_bf512d5aa6a0e4fe4d8be22b2ec4a1973c3d250fa1f65e47450322c25c45c0a0"
    ),
    "control_msgs/action/GripperCommand_Feedback": (
        "RIHS01_8f7c520077bab528bb9161ee3b83c81eee1f8aecadb8922ce82c79d667a819c4"
    ),
    "control_msgs/action/ParallelGripperCommand_Goal": (
        "RIHS01_412807b6b6acf2bf406fb0cf3b5c8f84286cd4e4d425734155aa1ff41caa0063"
    ),
    "control_msgs/action/ParallelGripperCommand_Result": (
        "RIHS01_51acbcd62aa44097d3877c506eab1146856fa8768628ffbe102c1699152d2afa"
    ),
    "control_msgs/action/ParallelGripperCommand_Feedback": (
        "RIHS01_ed6f7c4e5aea7f960432663c0e762e001a0a1f5cc0130d126e60041412d0543c"
    ),
    # sensor_msgs/JointState inside ParallelGripperCommand: its hash is part of the goal's.
    "sensor_msgs/msg/JointState": ("RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e"),
}


def _git_blob(data: bytes) -> str:
    return hashlib.sha1(b"blob %d\0" % len(data) + data).hexdigest()


@pytest.mark.parametrize("name", sorted(UPSTREAM_BLOBS))
def test_the_vendored_definitions_are_upstreams_byte_for_byte(name: str) -> None:
    assert _git_blob((VENDORED / name).read_bytes()) == UPSTREAM_BLOBS[name]


def _built_hashes() -> dict[str, str]:
    """The type hashes rosidl wrote into share/control_msgs/*/*.json when our control_msgs was built."""
    for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        share = Path(prefix) / "share" / "control_msgs"
        if share.is_dir():
            found: dict[str, str] = {}
            for path in sorted(share.glob("*/*.json")):
                for entry in json.loads(path.read_text(encoding="utf-8"))["type_hashes"]:
                    found[entry["type_name"]] = entry["hash_string"]
            return found
    raise AssertionError(
        f"no share/control_msgs under AMENT_PREFIX_PATH={os.environ.get('AMENT_PREFIX_PATH')!r}"
    )


@pytest.mark.ros2
@pytest.mark.skipif(bool(SKIP_REASON), reason=SKIP_REASON or "-")
@pytest.mark.parametrize("type_name", sorted(RIHS01))
def test_the_built_types_hash_as_upstreams(type_name: str) -> None:
    assert _built_hashes()[type_name] == RIHS01[type_name]


@pytest.mark.ros2
@pytest.mark.skipif(bool(SKIP_REASON), reason=SKIP_REASON or "-")
def test_the_python_types_are_the_built_ones() -> None:
    """The control_msgs rclpy imports is the one whose hashes were checked (not another on the path)."""
    import control_msgs

    module = Path(control_msgs.__file__).resolve()
    prefixes = [Path(p).resolve() for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    owner = next(p for p in prefixes if (p / "share" / "control_msgs").is_dir())
    assert owner in module.parents
