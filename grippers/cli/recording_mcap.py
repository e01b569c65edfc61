"""MCAP recordings (``grippers record -o run.mcap``): what ROS 2 tools and Foxglove open.

Two channels in one file (https://mcap.dev/spec): ``/joint_states``, a ``sensor_msgs/msg/JointState`` per
state in CDR (message encoding ``cdr``, schema encoding ``ros2msg``: the rosbag2 MCAP storage's own
conventions, https://mcap.dev/spec/registry), one joint whose position is the jaw width in m, velocity in m/s
and effort in N (empty when the device reports no force); and ``/grippers/record``, every row of the
recording (states and commands) as JSON, which :func:`read_mcap` reads back for ``grippers plot``. The
recording's header is an MCAP metadata record named ``grippers.record``.

The JointState schema is the message definition text as ROS 2 Jazzy ships it, with its dependencies appended
the way rosbag2 writes them (a line of 80 ``=``, then ``MSG: package/Type``): sensor_msgs/msg/JointState.msg
and std_msgs/msg/Header.msg from ros2/common_interfaces (branch jazzy), builtin_interfaces/msg/Time.msg from
ros2/rcl_interfaces (branch jazzy). ``mcap`` and ``mcap-ros2-support`` are the ``record`` extra, imported
here only.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import IO, Any

JOINT_STATE = "sensor_msgs/msg/JointState"
JOINT_TOPIC = "/joint_states"
JSON_TOPIC = "/grippers/record"
METADATA_NAME = "grippers.record"
JOINT_NAME = "gripper_joint"  # the joint name ``grippers ros2`` publishes (issue 21 §1)

_SEPARATOR = "=" * 80
_JOINT_STATE_MSG = """\
# This is a message that holds data to describe the state of a set of torque controlled joints.
#
# The state of each joint (revolute or prismatic) is defined by:
#  * the position of the joint (rad or m),
#  * the velocity of the joint (rad/s or m/s) and
#  * the effort that is applied in the joint (Nm or N).
#
# Each joint is uniquely identified by its name
# The header specifies the time at which the joint states were recorded. All the joint states
# in one message have to be recorded at the same time.
#
# This message consists of a multiple arrays, one for each part of the joint state.
# The goal is to make each of the fields optional. When e.g. your joints have no
# effort associated with them, you can leave the effort array empty.
#
# All arrays in this message should have the same size, or be empty.
# This is the only way to uniquely associate the joint name with the correct
# states.

std_msgs/Header header

string[] name
float64[] position
float64[] velocity
float64[] effort
"""
_HEADER_MSG = """\
# Standard metadata for higher-level stamped data types.
# This is generally used to communicate timestamped data
# in a particular coordinate frame.

# Two-integer timestamp that is expressed as seconds and nanoseconds.
builtin_interfaces/Time stamp

# Transform frame with which this data is associated.
string frame_id
"""
_TIME_MSG = """\
# This message communicates ROS Time defined here:
# https://design.ros2.org/articles/clock_and_time.html

# The seconds component, valid over all int32 values.
int32 sec

# The nanoseconds component, valid in the range [0, 1e9).
uint32 nanosec
"""
JOINT_STATE_DEFINITION = (
    _JOINT_STATE_MSG
    + f"\n{_SEPARATOR}\nMSG: std_msgs/Header\n"
    + _HEADER_MSG
    + f"\n{_SEPARATOR}\nMSG: builtin_interfaces/Time\n"
    + _TIME_MSG
)


class McapMissing(ImportError):
    """The ``record`` extra is not installed."""


def _modules() -> tuple[Any, Any]:
    try:
        from mcap.writer import CompressionType
        from mcap_ros2.writer import Writer
    except ImportError:
        raise McapMissing("MCAP recordings need the record extra: pip install 'grippers[record]'") from None
    return Writer, CompressionType


class McapSink:
    """An MCAP file opened before the gripper moves (so a bad path fails first) and written at the end."""

    def __init__(self, fh: IO[bytes]) -> None:
        writer_class, compression = _modules()
        self._fh = fh
        # Uncompressed: a recording is small, and every MCAP reader opens it without a codec package.
        self._ros = writer_class(fh, compression=compression.NONE)
        # mcap-ros2-support writes CDR channels only; the JSON channel goes through the same MCAP writer.
        self._raw = self._ros._writer
        self._joint = self._ros.register_msgdef(JOINT_STATE, JOINT_STATE_DEFINITION)
        # The JSON channel carries no schema record (schema id 0, which the MCAP spec allows): rosbag2-style
        # readers (rosbags) know only ROS schema encodings and refuse a file with a "jsonschema" one.
        self._json_channel = self._raw.register_channel(JSON_TOPIC, "json", 0)

    def write(self, header: Mapping[str, Any], rows: Iterable[Mapping[str, Any]]) -> None:
        self._raw.add_metadata(METADATA_NAME, {"json": json.dumps(dict(header))})
        start_ns = int(float(header.get("start_unix", 0.0)) * 1e9)
        for seq, row in enumerate(rows):
            stamp = start_ns + int(float(row["t_s"]) * 1e9)
            plain = {k: v for k, v in row.items() if v is not None}
            self._raw.add_message(
                self._json_channel,
                log_time=stamp,
                data=json.dumps(plain).encode(),
                publish_time=stamp,
                sequence=seq,
            )
            if row.get("kind") == "state":
                self._ros.write_message(
                    JOINT_TOPIC, self._joint, _joint_state(row, stamp), log_time=stamp, publish_time=stamp
                )
        self._ros.finish()
        self._fh.close()

    def abandon(self) -> None:
        self._fh.close()


def _joint_state(row: Mapping[str, Any], stamp_ns: int) -> dict[str, Any]:
    def si(key: str, scale: float) -> list[float]:
        value = row.get(key)
        return [] if value is None or not math.isfinite(float(value)) else [float(value) * scale]

    sec, nanosec = divmod(stamp_ns, 1_000_000_000)
    return {
        "header": {"stamp": {"sec": sec, "nanosec": nanosec}, "frame_id": ""},
        "name": [JOINT_NAME],
        "position": si("width_mm", 1e-3),
        "velocity": si("speed_mm_s", 1e-3),
        "effort": si("force_n", 1.0),
    }


def read_mcap(path: str | Path) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """(header, rows) of an MCAP recording: the ``grippers.record`` metadata and the JSON channel's rows.

    Raises ValueError (with the file named) for anything that is not such a recording."""
    try:
        from mcap.reader import make_reader
    except ImportError:
        raise McapMissing("reading MCAP needs the record extra: pip install 'grippers[record]'") from None
    header: dict[str, Any] = {}
    rows: list[dict[str, Any]] = []
    try:
        with open(path, "rb") as fh:
            reader = make_reader(fh)
            for meta in reader.iter_metadata():
                if meta.name == METADATA_NAME:
                    loaded = json.loads(meta.metadata.get("json", "{}"))
                    header = loaded if isinstance(loaded, dict) else {}
            fh.seek(0)
            reader = make_reader(fh)
            for _, _, message in reader.iter_messages(topics=[JSON_TOPIC]):
                rows.append(json.loads(message.data))
    except OSError as exc:
        raise ValueError(f"{path}: cannot read: {exc.strerror or exc}") from None
    except (
        Exception
    ) as exc:  # the mcap reader's own errors, struct errors, bad JSON: one line, the file named
        raise ValueError(
            f"{path}: not a readable MCAP recording: {' '.join(str(exc).split()) or type(exc).__name__}"
        ) from None
    return header, rows
