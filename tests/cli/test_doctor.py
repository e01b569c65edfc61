"""Issue 16 §2: `grippers doctor` checks the machine, one line per check with ok/warn/fail and the fix;
--json; exit 1 when something needed fails. The SocketCAN and vcan rules run on prepared /sys trees."""

from __future__ import annotations

import os
from pathlib import Path

from grippers.cli.doctor import check_serial_ports, check_socketcan, check_vcan


def _iface(root: Path, name: str, kind: str, operstate: str, flags: str) -> None:
    d = root / name
    d.mkdir(parents=True)
    (d / "type").write_text(kind + "\n")
    (d / "operstate").write_text(operstate + "\n")
    (d / "flags").write_text(flags + "\n")


def test_socketcan_states_and_bitrates(tmp_path: Path) -> None:
    _iface(tmp_path, "can0", "280", "up", "0x41")
    _iface(tmp_path, "can1", "280", "down", "0x80")
    _iface(tmp_path, "can2", "280", "up", "0x41")
    _iface(tmp_path, "eth0", "1", "up", "0x1003")  # not CAN: not listed

    def link(state: str, bitrate: int) -> dict:  # the shape of `ip -details -json link show`
        data = {"state": state, "bittiming": {"bitrate": bitrate}}
        return {"linkinfo": {"info_kind": "can", "info_data": data}}

    details = {
        "can0": link("ERROR-ACTIVE", 1000000),
        "can1": link("STOPPED", 500000),
        "can2": link("BUS-OFF", 1000000),
    }
    checks = {c.name: c for c in check_socketcan(str(tmp_path), details)}
    assert set(checks) == {"socketcan can0", "socketcan can1", "socketcan can2"}
    assert checks["socketcan can0"].status == "ok" and "1000000 bit/s" in checks["socketcan can0"].detail
    assert checks["socketcan can1"].status == "fail"
    assert checks["socketcan can1"].fix == "sudo ip link set can1 up type can bitrate 1000000"
    assert checks["socketcan can2"].status == "fail" and "bus-off" in checks["socketcan can2"].detail


def test_no_socketcan_interface_is_a_warning_with_the_fix(tmp_path: Path) -> None:
    (check,) = check_socketcan(str(tmp_path), {})
    assert check.status == "warn" and "setup-vcan.sh" in (check.fix or "")


def test_vcan_module(tmp_path: Path) -> None:
    assert check_vcan(str(tmp_path))[0].status == "warn"
    (tmp_path / "vcan").mkdir()
    assert check_vcan(str(tmp_path))[0].status == "ok"


def test_serial_port_permission(tmp_path: Path) -> None:
    port = tmp_path / "ttyFAKE0"
    port.write_text("")
    (ok,) = check_serial_ports([str(port)])
    assert ok.status == "ok"
    if os.geteuid() != 0:  # root opens anything; the permission rule is only observable as a user
        port.chmod(0)
        (denied,) = check_serial_ports([str(port)])
        assert denied.status == "fail" and "usermod -aG" in (denied.fix or "")
    assert check_serial_ports([])[0].status == "warn"


def test_doctor_runs_here(cli) -> None:
    r = cli("doctor", "--json")
    doc = r.json()
    assert r.returncode == (0 if doc["ok"] else 1)
    names = [c["name"] for c in doc["checks"]]
    assert names[:3] == ["python-can", "pyserial", "pydantic"]
    assert any(n.startswith("route to 192.168.1.20") for n in names)
    assert any(n == "extra plot" for n in names)
    assert all(c["fix"] for c in doc["checks"] if c["status"] != "ok")
    text = cli("doctor")
    lines = text.stdout.splitlines()
    assert all(line.split()[0] in ("OK", "WARN", "FAIL") for line in lines[: len(doc["checks"])])
