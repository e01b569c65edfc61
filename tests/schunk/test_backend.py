"""The SCHUNK family on the common interface (issue 41 §3), against the simulator over HTTP and RTU."""

from __future__ import annotations

import subprocess
import sys
import time

import pytest

import grippers
from grippers import CommandFailed, ConnectionLost, FastStopActive, GraspState, GripperTimeout
from grippers.drivers.schunk.protocol import Control, Status


def test_open_reads_the_unit_and_never_clears_its_power_up_error(schunk_sim) -> None:
    server = schunk_sim("schunk-egu-60", time_scale="20")
    with grippers.open(server.url) as g:
        assert server.model.commands == 0  # nothing but reads at open
        st = g.state()
        assert st.faults == ("ERR_FAST_STOP",) and st.referenced  # no reference run
        info = g.info()
        assert (info.model, info.serial, info.firmware) == ("EGU 60", "SIM00001", "5.3.0-90971")
        assert info.extra["module_type"] == "EGU_60_M_B" and info.extra["fieldbus"] == "EI"
        assert info.extra["firmware_text"] == "5.3.0.90971"  # as the unit writes it
        assert (g.limits.min_width, g.limits.max_width, g.limits.max_force) == (0.0, 0.12, 650.0)
        with pytest.raises(FastStopActive, match="ERR_FAST_STOP"):
            g.move(0.05)  # the unit refuses it (only the toggle), and says why
        g.acknowledge()
        g.home()  # ready: sends nothing
        assert g.move(0.05).width == pytest.approx(0.05, abs=1e-6)


def test_home_acknowledges_the_power_up_fast_stop(schunk_sim) -> None:
    server = schunk_sim("schunk-egk-25", time_scale="20")
    with grippers.open(server.url) as g:
        assert g.profile.name == "schunk-egk-25"  # chosen by the module type the unit reports (0x0500 = 17)
        g.home()
        assert g.state().referenced and g.state().faults == ()


def test_the_unit_narrows_the_profile_to_its_own_parameters(schunk_sim) -> None:
    server = schunk_sim("schunk-egk-25", time_scale="20")
    with server.lock:
        server.model.written[0x0600] = b"\x00\x00\xa0\x41"  # min_pos 20 mm, as on SCHUNK's EGK 25 unit
    with grippers.open(server.url) as g:
        assert g.limits.min_width == pytest.approx(0.020)
        with pytest.raises(grippers.LimitError):
            g.move(0.010)


def test_a_device_error_is_command_failed_with_its_code_and_name(schunk_sim) -> None:
    server = schunk_sim("schunk-egu-60", time_scale="2")
    with grippers.open(server.url) as g:
        g.home()
        handle = g.move(0.11, 0.01, wait=False)
        server.inject_error(0xEF)
        with pytest.raises(CommandFailed) as caught:
            handle.wait(10)
        assert caught.value.status == 0xEF and caught.value.status_name == "error 0xEF"
        assert g.state().faults == ("error 0xEF",)
        g.acknowledge()
        assert g.state().faults == ()


def test_grasp_force_is_a_whole_percentage_and_gpe_a_setting(schunk_sim) -> None:
    server = schunk_sim("schunk-egu-60", time_scale="20", part_width_mm="40")
    with grippers.open(server.url + "?gpe=true") as g:
        g.home()
        g.move(0.08)
        result = g.grasp(0.04, force=400.0)
        assert result.grasped and result.width == pytest.approx(0.040, abs=1e-6)
        assert server.model.output.force_percent == 62  # 400 N of 650 N, rounded to the unit's 1 %
        assert server.model.output.control & Control.GPE
        assert server.model.status & Status.GPE and g.state().grasp is GraspState.HOLDING
        g.release()
        assert g.state().width == pytest.approx(0.12, abs=1e-6)
    with grippers.open(server.url) as g:  # off by default
        g.grasp(0.04, force=400.0)
        assert not server.model.output.control & Control.GPE


def test_profinet_byte_order_end_to_end() -> None:
    with grippers.open("sim://schunk-egu-60?fieldbus=PN&time_scale=20") as g:
        assert g.info().extra["fieldbus"] == "PN"
        g.home()
        assert g.move(0.0333).width == pytest.approx(0.0333, abs=1e-6)


def test_an_unreachable_unit_is_connection_lost_and_a_silent_one_a_timeout(schunk_sim) -> None:
    server = schunk_sim("schunk-egu-60", time_scale="1")
    with grippers.open(server.url + "?timeout=0.3") as g:
        server.lose_connection(60)
        with pytest.raises(ConnectionLost, match="503"):
            g.state()
        server.lose_connection(0)
        g.state()
        server.faults.silent = True
        with pytest.raises(GripperTimeout):
            g.state()
        server.faults.silent = False


def test_rtu_url_with_a_slave_id(schunk_sim) -> None:
    server = schunk_sim("schunk-egu-60", "pty", time_scale="20", slave="5")
    assert server.url.endswith("?slave=5")
    with grippers.open(server.url) as g:
        g.home()
        assert g.move(0.07).width == pytest.approx(0.07, abs=1e-6)
        assert 20 < g.temperature() < 60
    with pytest.raises(GripperTimeout):
        grippers.open(server.url.replace("slave=5", "slave=6") + "&timeout=0.2")  # nobody answers id 6


def test_a_modbus_exception_reply_is_the_kit_s_typed_error(schunk_sim) -> None:
    from grippers.kit import ServerDeviceFailure

    server = schunk_sim("schunk-egu-60", "pty", time_scale="20")
    with grippers.open(server.url) as g:
        server.faults.exception_replies(4)
        with pytest.raises(ServerDeviceFailure, match="read holding registers") as caught:
            g.state()
        assert caught.value.status == 4 and caught.value.device == server.url
        assert g.state().width >= 0  # the next exchange is answered


def test_grippers_sim_schunk_prints_its_url_first() -> None:
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "grippers",
            "sim",
            "schunk",
            "--listen",
            "http://127.0.0.1:0",
            "--model",
            "egk-25",
        ],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout is not None
        first = proc.stdout.readline()
        assert "schunk+http://127.0.0.1:" in first, first
        url = first.split()[-1]
        with grippers.open(url) as g:
            assert g.profile.name == "schunk-egk-25"
    finally:
        proc.terminate()
        proc.wait(10)


def test_the_getting_started_example_runs_as_printed() -> None:
    from pathlib import Path

    page = (Path(__file__).resolve().parents[2] / "docs" / "getting-started-schunk.md").read_text()
    block = page.split("```python\n", 1)[1].split("```", 1)[0]
    out = subprocess.run([sys.executable, "-c", block], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["True", "40.0"]


def test_probe_finds_a_unit_on_a_bare_serial_port(schunk_sim) -> None:
    """``grippers probe /dev/ttyUSB0``: the unit at id 12 answers, and its module type names the model."""
    server = schunk_sim("schunk-egk-25", "pty")
    proc = subprocess.run(
        [sys.executable, "-m", "grippers", "probe", server.path, "--json", "--timeout", "0.3"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert "schunk+serial://" + server.path in proc.stdout, (proc.stdout, proc.stderr)
    assert "EGK 25" in proc.stdout


def test_wire_lines_at_debug_on_both_transports(schunk_sim, caplog: pytest.LogCaptureFixture) -> None:
    """``-vv`` shows every parameter exchange, decoded (docs/logging.md: wire lines for every family)."""
    import logging

    for listen in (None, "pty"):
        server = schunk_sim("schunk-egu-60", listen, time_scale="20")
        caplog.clear()
        with caplog.at_level(logging.DEBUG, logger="grippers.wire"), grippers.open(server.url) as g:
            g.home()
        lines = [r.getMessage() for r in caplog.records if r.name == "grippers.wire"]
        assert any("0x0040 plc_sync_input = ERROR|GPE at 0 um ERR_FAST_STOP" in ln for ln in lines), lines
        assert any("write 0x0048 plc_sync_output: FAST_STOP_OFF|ACKNOWLEDGE" in ln for ln in lines), lines


def test_soft_limits_are_the_units_position_limits(schunk_sim) -> None:
    server = schunk_sim("schunk-egu-60", time_scale="20")
    with grippers.open(server.url) as g:
        g.home()
        g.set_soft_limits(0.010, 0.100)
        assert server.model.read(0x0600, 0) == b"\x00\x00\x20\x41"  # 10.0 mm, little-endian float
        with pytest.raises(CommandFailed, match="not feasible"):
            g.move(0.110)  # the unit refuses a target outside its limits
        g.clear_soft_limits()
        assert g.move(0.110).width == pytest.approx(0.110, abs=1e-6)
    proc = subprocess.run(
        [sys.executable, "-m", "grippers", "settings", server.url, "--soft-limits", "5", "115", "--json"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 0, proc.stderr
    assert '"min_mm": 5.0' in proc.stdout and '"max_mm": 115.0' in proc.stdout, proc.stdout


def test_servo_streams_targets_as_move_commands(schunk_sim) -> None:
    server = schunk_sim("schunk-egu-60", time_scale="20")
    with grippers.open(server.url) as g:
        g.home()
        before = server.model.commands
        for mm in (40, 50, 60):
            g.servo(mm / 1000, speed=0.1)
            assert g.servo_flush(10)
            deadline = time.monotonic() + 10
            while abs(g.state().width - mm / 1000) > 1e-6 and time.monotonic() < deadline:
                time.sleep(0.01)
            assert g.state().width == pytest.approx(mm / 1000, abs=1e-6)
        assert server.model.commands - before >= 3
        assert g.move(0.02).width == pytest.approx(0.02, abs=1e-6)  # a motion after servoing
