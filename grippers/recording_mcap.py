"""MCAP recordings (``grippers record -o run.mcap``): what ROS 2 tools and Foxglove open.

Two channels in one file (https://mcap.dev/spec): ``/joint_states``, a ``sensor_msgs/msg/JointState`` per
state in CDR (message encoding ``cdr``, schema encoding ``ros2msg``: the rosbag2 MCAP storage's own
conventions, https://mcap.dev/spec/registry), one joint whose position is the jaw width in m, velocity in m/s
and effort in N (empty when the device reports no force); and ``/grippers/record``, every row of the
recording (states and commands) as JSON, which :func:`read_mcap` reads back for ``grippers plot``. The
recording's header is an MCAP metadata record named ``grippers.record``. Several grippers in one recording:
one JointState channel each, ``/NAME/joint_states``; the JSON channel names the gripper in every row.

The JointState schema is the message definition text as ROS 2 Jazzy ships it, with its dependencies appended
the way rosbag2 writes them (a line of 80 ``=``, then ``MSG: package/Type``): sensor_msgs/msg/JointState.msg
and std_msgs/msg/Header.msg from ros2/common_interfaces (branch jazzy), builtin_interfaces/msg/Time.msg from
ros2/rcl_interfaces (branch jazzy). ``mcap`` and ``mcap-ros2-support`` are the ``record`` extra, imported
here only.
"""

from __future__ import annotations

import json
import math
import struct
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from .units import split_ns, to_m, to_ns

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


FLUSH_CHUNK = 64 * 1024  # bytes: a chunk is finished at least this often (and at every flush())


def joint_topic(name: str, grippers: int) -> str:
    """``/joint_states`` for one gripper (as ``grippers ros2`` publishes it), ``/NAME/joint_states`` for
    each of several (as ``grippers ros2 --namespace NAME`` does)."""
    return JOINT_TOPIC if grippers <= 1 else f"/{name}{JOINT_TOPIC}"


class McapSink:
    """An MCAP file opened before the gripper moves (so a bad path fails first), written as rows come.

    Chunked, with every :meth:`flush` finishing the chunk in progress: a file cut short (a crash, a full
    disk) keeps every finished chunk, which :func:`read_mcap` reads; :meth:`finish` writes the summary."""

    def __init__(self, path: str | Path) -> None:
        writer_class, compression = _modules()
        self._fh = open(path, "wb")  # noqa: SIM115 (closed by close())
        try:
            # Uncompressed: a recording is small, and every MCAP reader opens it without a codec package.
            self._ros = writer_class(self._fh, chunk_size=FLUSH_CHUNK, compression=compression.NONE)
        except BaseException:
            self._fh.close()
            raise
        # mcap-ros2-support writes CDR channels only; the JSON channel goes through the same MCAP writer.
        self._raw = self._ros._writer
        self._joint: Any = None
        self._json_channel = 0
        self._start_ns = 0
        self._grippers = 1
        self._seq = 0

    def begin(self, header: Mapping[str, Any]) -> None:
        self._joint = self._ros.register_msgdef(JOINT_STATE, JOINT_STATE_DEFINITION)
        # The JSON channel carries no schema record (schema id 0, which the MCAP spec allows): rosbag2-style
        # readers (rosbags) know only ROS schema encodings and refuse a file with a "jsonschema" one.
        self._json_channel = self._raw.register_channel(JSON_TOPIC, "json", 0)
        self._raw.add_metadata(METADATA_NAME, {"json": json.dumps(dict(header))})
        self._start_ns = to_ns(float(header.get("start_unix", 0.0)))
        self._grippers = max(1, len(header.get("grippers", ())))
        self.flush()

    def add(self, row: Mapping[str, Any]) -> None:
        stamp = self._start_ns + to_ns(float(row["t_s"]))
        plain = {k: v for k, v in row.items() if v is not None}
        self._raw.add_message(
            self._json_channel,
            log_time=stamp,
            data=json.dumps(plain).encode(),
            publish_time=stamp,
            sequence=self._seq,
        )
        self._seq += 1
        if row.get("kind") == "state":
            topic = joint_topic(str(row.get("gripper")), self._grippers)
            self._ros.write_message(
                topic, self._joint, _joint_state(row, stamp), log_time=stamp, publish_time=stamp
            )

    def flush(self) -> None:
        flush = getattr(self._raw, "flush", None)  # mcap >= 1.2; older ones finish chunks by size only
        if flush is not None:
            flush()
        else:
            self._fh.flush()

    def finish(self) -> None:
        self._ros.finish()
        self._fh.flush()

    def close(self) -> None:
        self._fh.close()


def _joint_state(row: Mapping[str, Any], stamp_ns: int) -> dict[str, Any]:
    def si(key: str, convert: Callable[[float], float]) -> list[float]:
        value = row.get(key)
        return [] if value is None or not math.isfinite(float(value)) else [convert(float(value))]

    sec, nanosec = split_ns(stamp_ns)
    return {
        "header": {"stamp": {"sec": sec, "nanosec": nanosec}, "frame_id": ""},
        "name": [JOINT_NAME],
        "position": si("width_mm", to_m),
        "velocity": si("speed_mm_s", to_m),
        "effort": si("force_n", float),
    }


def read_mcap(path: str | Path) -> tuple[dict[str, Any], list[dict[str, Any]], str | None]:
    """(header, rows, cut) of an MCAP recording: the ``grippers.record`` metadata, the JSON channel's rows,
    and why the rest was left out of a file cut short (None: the file is whole).

    The file is read record by record from its start, not through its summary: a file whose writer was
    killed or ran out of disk has no summary, and every chunk before the cut still holds its rows.
    Raises ValueError (with the file named) for anything that is not such a recording."""
    try:
        from mcap.exceptions import McapError
        from mcap.records import Channel, Footer, Message, Metadata
        from mcap.stream_reader import CRCValidationError, StreamReader
    except ImportError:
        raise McapMissing("reading MCAP needs the record extra: pip install 'grippers[record]'") from None
    header: dict[str, Any] = {}
    rows: list[dict[str, Any]] = []
    json_channels: set[int] = set()
    whole = False
    cut: str | None = None
    try:
        with open(path, "rb") as fh:
            try:
                for record in StreamReader(fh, validate_crcs=True, record_size_limit=1 << 30).records:
                    if isinstance(record, Metadata) and record.name == METADATA_NAME:
                        loaded = json.loads(record.metadata.get("json", "{}"))
                        header = loaded if isinstance(loaded, dict) else {}
                    elif isinstance(record, Channel) and record.topic == JSON_TOPIC:
                        json_channels.add(record.id)
                    elif isinstance(record, Message) and record.channel_id in json_channels:
                        rows.append(json.loads(record.data))
                    elif isinstance(record, Footer):
                        whole = True
            except (EOFError, McapError, CRCValidationError, struct.error) as exc:
                if not header:  # not even the start of a recording
                    raise
                cut = f"it ends inside a record ({' '.join(str(exc).split()) or type(exc).__name__})"
        if not whole and cut is None:
            cut = "it has no summary (the writer did not finish)"
    except OSError as exc:
        raise ValueError(f"{path}: cannot read: {exc.strerror or exc}") from None
    except Exception as exc:  # the reader's own errors, struct errors, bad JSON: one line, the file named
        raise ValueError(
            f"{path}: not a readable MCAP recording: {' '.join(str(exc).split()) or type(exc).__name__}"
        ) from None
    return header, rows, cut
