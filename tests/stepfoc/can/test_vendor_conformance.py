"""Conformance with the vendor's library ``spectral-bldc`` (module ``Spectral_BLDC``), which real users run.

The vendor library drives our simulator over a python-can ``virtual`` bus; both sides must agree on every
field, except the object-detection value, where the vendor library reads the two bits in the wrong order and
reports 1 as 2 and 2 as 1 (docs/protocols.md §2; the firmware and we are right). That difference is asserted
explicitly.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator

import can
import pytest
from hypothesis import given
from hypothesis import strategies as st

from grippers.drivers.stepfoc.can_protocol import (
    Cmd,
    Detection,
    GripperCommand,
    GripperStatus,
    decode_command,
    decode_frame,
    encode_status,
    pack_id,
)
from grippers.drivers.stepfoc.sim import MsgModel
from grippers.drivers.stepfoc.sim.can_server import CanSimServer

from ..strategies import STATUS_FIELDS

Spectral_BLDC = pytest.importorskip("Spectral_BLDC")
from Spectral_BLDC import CAN_utils, CanCommunication, SpectralCAN  # noqa: E402

# the vendor library's reading of our detection value: 1 and 2 swapped
VENDOR_DETECTION = {0: 0, 1: 2, 2: 1, 3: 3}


@pytest.fixture
def vendor_comm(channel: str) -> Iterator[CanCommunication]:
    comm = CanCommunication(channel=None)  # channel None: the library opens no bus, we hand it one
    comm.bus = can.Bus(interface="virtual", channel=channel)
    yield comm
    comm.bus.shutdown()


def vendor_receive(
    comm: CanCommunication, vendor: SpectralCAN, command: int, timeout: float = 1.0
) -> can.Message:
    """Read frames with the vendor library until one of ``command`` for this node; unpack it vendor-side."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        message, ids = comm.receive_can_messages(timeout=0.1)
        if message is None or ids.node_id != vendor.node_id or ids.command_id != command:
            continue
        vendor.UnpackData(message, ids)
        return message
    raise AssertionError(f"no frame {command} from node {vendor.node_id}")


def vendor_status(comm: CanCommunication, vendor: SpectralCAN) -> GripperStatus:
    """Poll with the vendor's empty 61; return OUR decoding of the same frame the vendor just unpacked."""
    vendor.Send_gripper_data_pack()
    msg = vendor_receive(comm, vendor, SpectralCAN.RESPOND_GRIPPER_DATA_PACK_ID)
    return decode_frame(msg.arbitration_id, msg.data, msg.is_remote_frame).value


def assert_same_status(ours: GripperStatus, vendor: SpectralCAN) -> None:
    assert vendor.gripper_position == ours.position
    assert vendor.gripper_current == ours.current_ma
    assert vendor.gripper_activated == ours.activated
    assert vendor.gripper_action_status == ours.action
    assert vendor.gripper_temperature_error == ours.temperature_error
    assert vendor.gripper_timeout_error == ours.timeout_error
    assert vendor.gripper_estop_error == ours.estop_error
    assert vendor.gripper_calibrated == ours.calibrated
    assert vendor.gripper_object_detection == VENDOR_DETECTION[ours.detection]  # the vendor's swap


def test_identifiers_agree() -> None:
    for node in range(16):
        for command in range(64):
            for err in (0, 1):
                arbitration_id = pack_id(node, command, bool(err))
                assert CAN_utils.combine_2_can_id(node, command, err) == arbitration_id
                assert CAN_utils.extract_from_can_id(arbitration_id) == (node, command, err)


@given(
    st.integers(0, 255),
    st.integers(0, 255),
    st.integers(-32768, 32767),
    st.booleans(),
    st.booleans(),
    st.booleans(),
    st.booleans(),
)
def test_vendor_command_bytes_decode_to_the_same_fields(
    position: int, speed: int, current: int, activate: bool, action: bool, estop: bool, release: bool
) -> None:
    sent: list[tuple[int, bytes]] = []

    class Capture:  # stands in for the vendor's CanCommunication: records what the library would send
        def send_can_message(self, message_id: int, data: bytes = b"", remote_frame: bool = False) -> None:
            sent.append((message_id, bytes(data)))

    SpectralCAN(3, Capture()).Send_gripper_data_pack(
        position, speed, current, int(activate), int(action), int(estop), int(release)
    )
    ((arbitration_id, data),) = sent
    assert arbitration_id == pack_id(3, Cmd.GRIPPER_COMMAND)
    assert decode_command(data) == GripperCommand(position, speed, current, activate, action, estop, release)


@given(st.builds(GripperStatus, **STATUS_FIELDS))
def test_our_status_bytes_read_by_vendor(status: GripperStatus) -> None:
    vendor = SpectralCAN(0, None)
    msg = can.Message(arbitration_id=pack_id(0, 60), data=encode_status(status), is_extended_id=False)
    vendor.UnpackData(msg, _ids(msg))
    assert_same_status(status, vendor)


def _ids(msg: can.Message) -> object:
    from Spectral_BLDC.Spectral_BLDC import CanMessage

    return CanMessage(*CAN_utils.extract_from_can_id(msg.arbitration_id))


@pytest.mark.parametrize(
    ("detection", "vendor_value"),
    [
        (Detection.MOVING, 0),
        (Detection.CLOSING_OBJECT, 2),
        (Detection.OPENING_OBJECT, 1),
        (Detection.AT_POSITION, 3),
    ],
)
def test_vendor_swaps_detection_1_and_2(detection: Detection, vendor_value: int) -> None:
    status = GripperStatus(10, -500, True, True, detection, False, False, False, True)
    msg = can.Message(arbitration_id=pack_id(0, 60), data=encode_status(status), is_extended_id=False)
    vendor = SpectralCAN(0, None)
    vendor.UnpackData(msg, _ids(msg))
    assert vendor.gripper_object_detection == vendor_value


def test_vendor_drives_simulator_end_to_end(
    start_sim: Callable[..., CanSimServer], vendor_comm: CanCommunication
) -> None:
    server = start_sim(
        MsgModel(node=2, part_width_mm=40.0), MsgModel(node=5, part_width_mm=30.0, part_grip="inside")
    )
    grip = SpectralCAN(2, vendor_comm)
    inside = SpectralCAN(5, vendor_comm)
    model = server.models[0]

    ours = vendor_status(vendor_comm, grip)
    assert not ours.calibrated
    assert_same_status(ours, grip)

    for g in (grip, inside):
        g.Send_gripper_calibrate()
    for g in (grip, inside):
        deadline = time.monotonic() + 5.0
        while not (ours := vendor_status(vendor_comm, g)).calibrated:  # empty polls do not abort calibration
            assert time.monotonic() < deadline
            time.sleep(0.01)
        assert_same_status(ours, g)
        assert ours.position == 255

    # a command as the vendor sends it: all fields land in the model
    grip.Send_gripper_data_pack(0, 250, 500, 1, 1, 0, 0)
    vendor_receive(vendor_comm, grip, SpectralCAN.RESPOND_GRIPPER_DATA_PACK_ID)
    assert (model.position_setpoint, model.speed_setpoint, model.current_setpoint) == (0, 250, 500)
    assert model.activated and model.action and not model.estop
    deadline = time.monotonic() + 5.0
    while (ours := vendor_status(vendor_comm, grip)).detection is not Detection.AT_POSITION:  # fully open
        assert time.monotonic() < deadline
    assert_same_status(ours, grip)
    assert ours.position == 0 and grip.gripper_object_detection == 3

    # close onto the part: firmware detection 1, which the vendor reports as 2
    grip.Send_gripper_data_pack(255, 255, 500, 1, 1, 0, 0)
    deadline = time.monotonic() + 5.0
    while (ours := vendor_status(vendor_comm, grip)).detection is not Detection.CLOSING_OBJECT:
        assert time.monotonic() < deadline
    assert_same_status(ours, grip)
    assert grip.gripper_object_detection == 2 and ours.current_ma < 0

    # open against an inside-grip part: firmware 2, vendor 1
    inside.Send_gripper_data_pack(0, 255, 400, 1, 1, 0, 0)
    deadline = time.monotonic() + 5.0
    while (ours := vendor_status(vendor_comm, inside)).detection is not Detection.OPENING_OBJECT:
        assert time.monotonic() < deadline
    assert_same_status(ours, inside)
    assert inside.gripper_object_detection == 1 and ours.current_ma > 0

    # at position: 3 on both sides
    grip.Send_gripper_data_pack(100, 255, 500, 1, 1, 0, 0)
    deadline = time.monotonic() + 5.0
    while (ours := vendor_status(vendor_comm, grip)).detection is not Detection.AT_POSITION:
        assert time.monotonic() < deadline
    assert_same_status(ours, grip)


def test_vendor_remote_requests(
    start_sim: Callable[..., CanSimServer], vendor_comm: CanCommunication
) -> None:
    server = start_sim(
        MsgModel(
            node=4,
            hardware_version=3,
            batch_date=22,
            software_version=17,
            serial=77777,
            temperature_c=-4,
            bus_voltage_mv=23_500,
            current_noise=False,  # the vendor's value is compared with the model's true current
        )
    )
    model = server.model
    v = SpectralCAN(4, vendor_comm)

    v.Send_Respond_Ping()
    vendor_receive(vendor_comm, v, SpectralCAN.SEND_RESPOND_PING_ID)
    assert v.ping == 1
    v.Send_Respond_Device_Info()
    vendor_receive(vendor_comm, v, SpectralCAN.SEND_RESPOND_DEVICE_INFO_ID)
    assert (v.HARDWARE_VERSION, v.BATCH_DATE, v.SOFTWARE_VERSION, v.SERIAL_NUMBER) == (3, 22, 17, 77777)
    v.Send_Respond_Temperature()
    vendor_receive(vendor_comm, v, SpectralCAN.SEND_RESPOND_TEMPERATURE_ID)
    assert v.temperature == -4
    v.Send_Respond_Voltage()
    vendor_receive(vendor_comm, v, SpectralCAN.SEND_RESPOND_VOLTAGE_ID)
    assert v.voltage == 23_500
    v.Send_Respond_Iq_data()
    vendor_receive(vendor_comm, v, SpectralCAN.SEND_RESPOND_IQ_DATA_ID)
    assert v.current == model.current_ma
    v.Send_Respond_Encoder_data()
    vendor_receive(vendor_comm, v, SpectralCAN.SEND_RESPOND_ENCODER_DATA_ID)
    assert v.position == model.encoder().position and v.speed == model.encoder().velocity

    v.Send_ESTOP()
    v.Send_Respond_State_of_Errors()
    msg = vendor_receive(vendor_comm, v, SpectralCAN.SEND_RESPOND_STATE_OF_ERRORS_ID)
    ours = decode_frame(msg.arbitration_id, msg.data).value
    assert msg.arbitration_id & 1  # error bit while the estop error is active
    names = (
        "error",
        "temperature_error",
        "encoder_error",
        "vbus_error",
        "driver_error",
        "velocity_error",
        "current_error",
        "estop_error",
        "calibrated",
        "activated",
        "watchdog_error",
    )
    fields = (
        "error",
        "temperature",
        "encoder",
        "vbus",
        "driver",
        "velocity",
        "current",
        "estop",
        "calibrated",
        "activated",
        "watchdog",
    )
    assert [getattr(v, n) for n in names] == [int(getattr(ours, f)) for f in fields]
    assert v.estop_error == 1 and v.error == 1

    v.Send_Clear_Error()
    ours_status = vendor_status(vendor_comm, v)
    assert not ours_status.estop_error
    assert_same_status(ours_status, v)


def test_vendor_configuration_commands(
    start_sim: Callable[..., CanSimServer], vendor_comm: CanCommunication
) -> None:
    server = start_sim(MsgModel(node=1))
    model = server.model
    v = SpectralCAN(1, vendor_comm)
    v.Send_Watchdog(1500, "Hold")
    v.Send_Heartbeat_Setup(20)
    vendor_receive(vendor_comm, v, SpectralCAN.RESPOND_HEARTBEAT_ID)
    assert v.heartbeat == 1
    assert model.watchdog.timeout_ms == 1500 and model.watchdog.action == 1
    v.Send_Heartbeat_Setup(0)
    v.Send_Idle()
    v.Send_CAN_ID(12)
    v2 = SpectralCAN(12, vendor_comm)
    v2.Send_Save_config()
    vendor_status(vendor_comm, v2)
    assert model.node == 12 and model.saved_node == 12 and model.heartbeat_ms == 0
