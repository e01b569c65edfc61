"""Issue 31 §4: python-can's gs_usb interface needs pyusb (and gs-usb), which python-can does not install;
opening it without them names the extra that does, on every family's CAN transport."""

from __future__ import annotations

import sys

import pytest

import grippers


@pytest.mark.parametrize("url", ["stepfoc+can://gs_usb/0?node=0", "wsg+can://gs_usb/0"])
def test_gs_usb_without_pyusb_names_the_extra(monkeypatch: pytest.MonkeyPatch, url: str) -> None:
    # What python-can meets when pyusb is missing: its module for the interface fails to import.
    monkeypatch.setitem(sys.modules, "usb", None)
    monkeypatch.setitem(sys.modules, "gs_usb", None)
    monkeypatch.delitem(sys.modules, "can.interfaces.gs_usb", raising=False)
    with pytest.raises(grippers.GripperError) as caught:
        grippers.open(url, timeout=0.5)
    text = str(caught.value)
    assert "pip install 'grippers[usb]'" in text and "pyusb" in text and "gs_usb" in text


def test_other_interfaces_keep_python_cans_message() -> None:
    import can

    from grippers.drivers.canlink import open_bus

    with pytest.raises(can.CanInterfaceNotImplementedError) as caught:
        open_bus(interface="no_such_interface", channel="0")
    assert "grippers[" not in str(caught.value)
