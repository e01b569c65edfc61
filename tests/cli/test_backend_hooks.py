"""``grippers.backends.hook``: where the CLI finds what a family offers (issue 28 §2).

A family's CLI module (``X_cli`` beside its backend's module ``X``) is asked first, then the backend object;
a backend in a top-level module (a plugin's) has only its attributes; a family without the hook gives None,
and the command says so in words that fit every family.
"""

from __future__ import annotations

import sys
import types

import pytest

from grippers.backends import find_backend, hook


def _install(monkeypatch: pytest.MonkeyPatch, name: str, **attrs: object) -> types.ModuleType:
    module = types.ModuleType(name)
    for key, value in attrs.items():
        setattr(module, key, value)
    monkeypatch.setitem(sys.modules, name, module)
    return module


def test_the_cli_module_wins_over_the_backend(monkeypatch: pytest.MonkeyPatch) -> None:
    import grippers.backends as registry

    monkeypatch.setattr(registry, "_cli_modules", {})
    backend_module = _install(monkeypatch, "grippers.backends._hooktest")
    _install(monkeypatch, "grippers.backends._hooktest_cli", factory_address="tcp://10.0.0.9:7")

    class Backend:
        factory_address = "tcp://10.0.0.1:1"
        bare_forms = {"tcp": (1, "x+tcp://{rest}")}

    Backend.__module__ = backend_module.__name__
    backend = Backend()
    assert hook(backend, "factory_address") == "tcp://10.0.0.9:7"  # the CLI module's
    assert hook(backend, "bare_forms") == {"tcp": (1, "x+tcp://{rest}")}  # not there: the backend's
    assert hook(backend, "dissector") is None  # offered by neither


def test_a_top_level_plugin_has_its_attributes_only(monkeypatch: pytest.MonkeyPatch) -> None:
    import grippers.backends as registry

    monkeypatch.setattr(registry, "_cli_modules", {})
    _install(monkeypatch, "hooktest_plugin")
    _install(monkeypatch, "hooktest_plugin_cli", factory_address="tcp://10.0.0.9:7")  # not its CLI module

    class Backend:
        pass

    Backend.__module__ = "hooktest_plugin"
    assert hook(Backend(), "factory_address") is None
    assert hook(None, "dissector") is None  # an unknown family


def test_a_missing_cli_module_is_no_hook_a_broken_one_an_error(monkeypatch: pytest.MonkeyPatch) -> None:
    import grippers.backends as registry

    monkeypatch.setattr(registry, "_cli_modules", {})

    class Quiet:
        pass

    Quiet.__module__ = "grippers.backends._no_such_family"
    assert hook(Quiet(), "dissector") is None

    def broken_import(name: str, *args: object, **kwargs: object) -> object:
        raise ModuleNotFoundError("No module named 'needed_extra'", name="needed_extra")

    class Broken:
        pass

    Broken.__module__ = "grippers.backends._broken_family"
    monkeypatch.setattr(registry.importlib, "import_module", broken_import)
    with pytest.raises(ModuleNotFoundError, match="needed_extra"):
        hook(Broken(), "dissector")


def test_the_built_in_families_ports_come_from_their_profile_models() -> None:
    """The WSG's factory address, probe ports and serial speed are its profile model's (issue 32 §4)."""
    from grippers.backends.wsg_profile import WsgTransport
    from grippers.urls import parse_url

    wsg = find_backend("wsg")
    t = WsgTransport()
    assert hook(wsg, "factory_address") == f"tcp://192.168.1.20:{t.tcp_port}"
    probe = hook(wsg, "probe_candidates")
    assert [c.url for c in probe("udp", parse_url("udp://10.0.0.5", bare_family="bare"), {})] == [
        f"wsg+udp://10.0.0.5:{t.udp_port}"
    ]
    serial = probe("serial", parse_url("serial:///dev/ttyX", bare_family="bare"), {})
    assert serial[0].url.endswith(f"?baudrate={t.baudrate}")
