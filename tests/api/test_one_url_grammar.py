"""Issue 20 §1, "One URL grammar": every URL in the tree is read by ``drivers/urls.py``.

Before, the drivers, the simulators' listen URLs and five CLI modules each split URLs themselves and drifted:
a ``#fragment``, a user name or a path after ``host:port`` was silently dropped by some and kept by others, a
``bitrate=`` left blank was ignored, a key given twice was resolved differently, and a slcan channel lost its
leading slash in ``grippers.open`` but not in the STEPFOC driver. These tests hold every entry point to the
same answer: the grammar's :class:`URLError`, naming the URL.
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import grippers
from grippers import URLError
from grippers.cli import main as cli_main
from grippers.cli.output import UsageError
from grippers.cli.probe_targets import expand, location_of
from grippers.drivers import urls as driver_urls
from grippers.drivers.stepfoc.can_protocol import parse_can_url
from grippers.drivers.wsg.client import WsgClient
from grippers.drivers.wsg.sim.model import WsgModel
from grippers.drivers.wsg.sim.server import serve
from grippers.remote.discovery import served_urls
from grippers.urls import parse_url

ROOT = Path(__file__).resolve().parents[2]
URL_PARSERS = re.compile(r"\b(urlsplit|urlparse|parse_qsl|parse_qs)\b")


def test_the_url_parsers_of_the_standard_library_are_called_only_by_the_grammar() -> None:
    users = sorted(
        str(path.relative_to(ROOT))
        for folder in ("drivers", "grippers")
        for path in (ROOT / folder).rglob("*.py")
        if URL_PARSERS.search(path.read_text(encoding="utf-8"))
    )
    assert users == ["drivers/urls.py"]


def test_the_api_names_are_the_drivers_grammar_not_a_copy() -> None:
    # grippers.urls.parse_url is the drivers' grammar plus the families' own schemes (robotiq+urcap://,
    # schunk+http://), which it rewrites into that grammar: it delegates, it does not parse a second time.
    assert grippers.urls.parse_transport_url is driver_urls.parse_url
    for url in ("wsg+tcp://127.0.0.1:1000?timeout=1", "sim://wsg50?transport=udp", "robotiq+serial:///dev/x"):
        assert parse_url(url) == driver_urls.parse_url(url)
    assert parse_url("schunk+http://10.0.0.5") == dataclasses.replace(
        driver_urls.parse_url("schunk+tcp://10.0.0.5?protocol=http"), url="schunk+http://10.0.0.5"
    )
    assert grippers.URLError is driver_urls.URLError
    assert issubclass(URLError, ValueError) and issubclass(URLError, grippers.GripperError)


# Each hostile URL once per family of entry point: (what the user wrote, a piece of it the error must quote).
HOSTILE_CLIENT = [
    ("wsg+tcp://127.0.0.1:1#x", "#x"),  # a fragment was dropped: the gripper at :1 was dialled
    ("wsg+tcp://admin@127.0.0.1:1", "admin@"),  # a user name was dropped
    ("wsg+tcp://127.0.0.1:1/pos", "/pos"),  # a path was dropped
    ("wsg+tcp://127.0.0.1\n:1", "127.0.0.1"),  # a newline was stripped by urlsplit
    ("wsg+tcp://[::1:1", "[::1:1"),  # an unclosed IPv6 bracket
    ("wsg+tcp://::1:1", "::1:1"),  # IPv6 without brackets
    ("wsg+tcp://127.0.0.1:\u0661", "127.0.0.1"),  # an Arabic-Indic digit as the port
    ("wsg+udp://127.0.0.1:1?local_port=1&local_port=2", "local_port"),  # which one?
    ("wsg+udp://127.0.0.1:1?local_port", "local_port"),  # a field without "="
    ("wsg+udp://127.0.0.1:1?=5", "127.0.0.1"),  # a value without a key
    ("wsg+can://virtual/ch?send_id=0x10%0a", "send_id"),  # a decoded control character
    ("wsg+can://virtual/ch#2", "#2"),
]


def _message_names(exc: BaseException, url: str, piece: str) -> None:
    text = str(exc)
    assert piece in text or repr(piece)[1:-1] in text, text
    assert repr(url)[:30] in text or url[:30] in text, text


@pytest.mark.parametrize(("url", "piece"), HOSTILE_CLIENT)
@pytest.mark.parametrize(
    "entry",
    [
        pytest.param(parse_url, id="grippers.urls.parse_url"),
        pytest.param(grippers.open, id="grippers.open"),
        pytest.param(lambda u: WsgClient.from_url(u, timeout=0.2), id="WsgClient.from_url"),
        pytest.param(location_of, id="probe location"),
        pytest.param(expand, id="probe target"),
    ],
)
def test_hostile_client_urls_are_the_same_url_error_everywhere(
    entry: Callable[[str], Any], url: str, piece: str
) -> None:
    with pytest.raises(URLError) as info:
        entry(url)
    _message_names(info.value, url, piece)


@pytest.mark.parametrize(
    "entry",
    [
        pytest.param(grippers.open, id="grippers.open"),
        pytest.param(lambda u: WsgClient.from_url(u, timeout=0.2), id="WsgClient.from_url"),
    ],
)
def test_a_blank_number_is_a_url_error_where_it_is_read(entry: Callable[[str], Any]) -> None:
    """``bitrate=`` is an empty value to the grammar; the driver's parse_qs dropped it, using its default."""
    url = "wsg+can://virtual/wsg-url-blank?bitrate="
    with pytest.raises(URLError, match="bitrate must be an integer"):
        entry(url)


def test_a_probe_target_error_is_both_the_grammars_error_and_a_usage_error() -> None:
    with pytest.raises(UsageError) as info:
        expand("tcp://127.0.0.1:1#x")
    assert isinstance(info.value, URLError)


HOSTILE_LISTEN = [
    ("tcp://127.0.0.1:0#x", "#x"),  # served before, on the port without the fragment
    ("tcp://127.0.0.1:0/x", "/x"),
    ("udp://a@127.0.0.1:0", "a@"),
    ("can://virtual/wsg-url-test?bitrate=", "bitrate"),  # served before, the blank bitrate ignored
    ("can://virtual/wsg-url-test?send_id=1&send_id=2", "send_id"),
    ("can://virtual/wsg-url-test?extended=maybe", "extended"),  # read as "no" before
]


@pytest.mark.parametrize(("listen", "piece"), HOSTILE_LISTEN)
def test_hostile_listen_urls_of_the_wsg_simulator_are_url_errors(listen: str, piece: str) -> None:
    with pytest.raises(URLError) as info:
        server = serve(WsgModel(), listen)
        server.close()  # pragma: no cover - only reached by the bug this test is about
    _message_names(info.value, listen, piece)


@pytest.mark.parametrize(
    ("url", "piece"),
    [
        ("stepfoc+can://virtual/ch#1?node=2", "#1"),  # the hand parser took "ch#1" for the channel
        ("stepfoc+can://virtual/ch?node=1&node=2", "node"),  # last one won: the other gripper was driven
        ("can://virtual/ch?node=1&&bitrate=5", "malformed"),
        ("stepfoc+can://[virtual/ch", "[virtual"),
    ],
)
def test_hostile_can_urls_of_the_stepfoc_driver_and_simulator_are_url_errors(url: str, piece: str) -> None:
    with pytest.raises(URLError) as info:
        parse_can_url(url)  # StepfocBus.from_url and serve_can both read their URL here
    _message_names(info.value, url, piece)
    if url.startswith("stepfoc+"):
        with pytest.raises(URLError):
            parse_url(url)


def test_a_hostile_zenoh_discovery_target_is_a_url_error_before_any_session() -> None:
    with pytest.raises(URLError, match="connect"):
        served_urls("zenoh://?connect=tcp/127.0.0.1:1&connect=tcp/127.0.0.1:2", timeout=0.1)
    with pytest.raises(URLError, match="malformed"):
        served_urls("zenoh://?connect", timeout=0.1)


def _cli(*argv: str) -> tuple[int, str]:
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = cli_main(list(argv))
    return code, err.getvalue()


@pytest.mark.parametrize(
    ("argv", "says"),
    [
        (("probe", "tcp://127.0.0.1:1#x", "--timeout", "0.2"), "no #fragment"),
        (("probe", "wsg+tcp://admin@127.0.0.1:1", "--timeout", "0.2"), "no user name"),
        (("state", "wsg+tcp://127.0.0.1:1/pos"), "no path"),
        (("sim", "wsg", "--listen", "tcp://127.0.0.1:0#x"), "no #fragment"),
        (("sim", "msg", "--listen", "can://virtual/msg-url-test?node=1&node=2"), "node given twice"),
    ],
)
def test_the_cli_reports_the_grammars_error_as_a_usage_error(argv: tuple[str, ...], says: str) -> None:
    code, err = _cli(*argv)
    assert code == 2, err
    assert says in err, err


@pytest.mark.parametrize(
    "url",
    [
        "wsg+can://slcan//dev/ttyACM0@115200",
        "stepfoc+can://slcan//dev/ttyACM0@115200?node=2",
        "stepfoc+can://udp_multicast/ff15::7079:1?node=1",
        "wsg+can://socketcan/can%30",
    ],
)
def test_one_reading_of_a_can_url_from_the_api_the_driver_and_the_probe(url: str) -> None:
    """After the first ``/`` everything is the channel: grippers.open had dropped a slcan device's leading
    slash (``dev/ttyACM0``) where the STEPFOC driver kept it; the driver did not percent-decode."""
    api = parse_url(url)
    assert api.channel is not None and api.channel == location_of(url)["channel"]
    if url.startswith("stepfoc+"):
        assert parse_can_url(url)[:2] == (api.interface, api.channel)
    if "slcan" in url:
        assert api.channel.startswith("/dev/ttyACM0")
    if url.endswith("%30"):
        assert api.channel == "can0"


def test_a_key_given_twice_with_one_value_is_accepted() -> None:
    assert parse_url("wsg+udp://h:1?local_port=5&local_port=5").params == {"local_port": "5"}


def test_listen_urls_may_leave_out_the_host_and_ask_for_any_port() -> None:
    u = driver_urls.parse_url("tcp://:0", bare_family="wsg", listen=True)
    assert (u.family, u.transport, u.host, u.port) == ("wsg", "tcp", None, 0)
    with pytest.raises(URLError, match="port 0"):
        driver_urls.parse_url("wsg+tcp://h:0")
    with pytest.raises(URLError, match="no host"):
        driver_urls.parse_url("wsg+tcp://:1000")


def test_ipv6_hosts_and_zones_round_trip_through_format_host() -> None:
    for host in ("::1", "fe80::1%eth0", "127.0.0.1", "gripper.local"):
        url = f"wsg+tcp://{driver_urls.format_host(host, 1000)}"
        assert (parse_url(url).host, parse_url(url).port) == (host, 1000)


def test_a_megabyte_of_url_gives_a_short_message() -> None:
    url = "wsg+tcp://h:1?" + "x" * 1_000_000
    with pytest.raises(URLError) as info:
        parse_url(url)
    assert len(str(info.value)) < 1000


@settings(max_examples=300, deadline=None)
@given(
    st.text(alphabet=st.sampled_from(list("wsg+tcpudpcanserial:/?&=#%[]@.01x\n \u0661")), max_size=40),
    st.sampled_from([None, "wsg"]),
    st.booleans(),
)
def test_any_text_is_a_parsed_url_or_a_url_error(text: str, bare: str | None, listen: bool) -> None:
    try:
        u = driver_urls.parse_url(text, bare_family=bare, listen=listen)
    except URLError as exc:
        assert str(exc)
        return
    assert u.url == text
    assert u.port is None or 0 <= u.port <= 65535
    for value in (u.host, u.serial_port, u.interface, u.channel, u.profile, *u.params, *u.params.values()):
        assert value is None or not re.search(r"[\x00-\x1f\x7f]", value)


def test_with_params_sets_a_parameter_and_keeps_the_others_as_written() -> None:
    """``grippers settings --node-id`` hands back the node's new URL; it filtered ``node=`` by hand before."""
    w = driver_urls.with_params
    assert (
        w("stepfoc+can://virtual/ch?bitrate=5&node=0", node=3) == "stepfoc+can://virtual/ch?node=3&bitrate=5"
    )
    assert w("stepfoc+can://virtual/ch", node=3) == "stepfoc+can://virtual/ch?node=3"
    assert parse_url(w("stepfoc+can://virtual/ch?n%6Fde=1", node=2)).params == {"node": "2"}
    with pytest.raises(URLError):
        w("stepfoc+can://virtual/ch#x", node=2)


def test_a_simulator_on_ipv6_loopback_names_a_url_the_grammar_reads_back() -> None:
    try:
        server = serve(WsgModel(), "tcp://[::1]:0")
    except OSError:
        pytest.skip("no IPv6 loopback on this machine")
    try:
        u = parse_url(server.url)
        assert (u.host, u.port) == ("::1", server.address[1])
        with WsgClient.from_url(server.url, timeout=2.0) as client:
            assert client.system_info() is not None
    finally:
        server.close()


# Issue 40 §6: the readers the callers used to write by hand, one rule each (tests/test_readable_tree.py
# fails on a hand-written copy).


def test_scheme_of_is_the_scheme_the_grammar_reads() -> None:
    assert driver_urls.scheme_of("CAN://virtual/x") == "can"
    assert driver_urls.scheme_of("wsg+serial://socket://h:4000") == "wsg+serial"
    assert driver_urls.scheme_of("/dev/ttyUSB0") == driver_urls.scheme_of(None) == ""


@pytest.mark.parametrize(
    ("text", "listen", "expected"),
    [
        ("127.0.0.1:8000", False, ("127.0.0.1", 8000)),
        ("[::1]:7447", False, ("::1", 7447)),
        ("[fe80::1%25eth0]:1", False, ("fe80::1%eth0", 1)),
        ("gripper.local:1000", False, ("gripper.local", 1000)),
        (":8000", True, (None, 8000)),
        ("0.0.0.0:0", True, ("0.0.0.0", 0)),
    ],
)
def test_parse_address_reads_host_and_port_by_the_urls_rules(
    text: str, listen: bool, expected: tuple[str | None, int]
) -> None:
    assert driver_urls.parse_address(text, listen=listen) == expected


@pytest.mark.parametrize(
    "text", ["127.0.0.1", "h:70000", "h:x", "::1:80", "[::1", "a..b:1", "h:0", ":80", "u@h:1", "h\n:1"]
)
def test_parse_address_refuses_what_a_url_refuses(text: str) -> None:
    with pytest.raises(URLError):
        driver_urls.parse_address(text)


def test_zenoh_endpoints_are_checked_before_any_session() -> None:
    z = driver_urls.zenoh_endpoint
    assert z("tcp/127.0.0.1:7447", "--listen") == ("tcp", "127.0.0.1", 7447)
    assert z("tls/[::1]:0#iface=lo", "--listen") == ("tls", "::1", 0)
    assert z("unixsock-stream/tmp/sock", "--listen") == ("unixsock-stream", None, None)
    for bad in ("tcp/127.0.0.1:99999", "tcp/:7447", "tcp", "/x", "tcp/h"):
        with pytest.raises(URLError, match="--connect"):
            z(bad, "--connect")
    assert driver_urls.zenoh_endpoints("tcp/a:1,,tcp/b:2", "connect") == ["tcp/a:1", "tcp/b:2"]
    assert driver_urls.zenoh_port("tcp/h:0") == 0 and driver_urls.zenoh_port("tcp/h:x") is None


def test_a_family_scheme_of_a_listen_url_goes_onto_its_transport() -> None:
    t = driver_urls.on_transport
    assert t("urcap://127.0.0.1:0", {"urcap": "tcp"}) == ("tcp://127.0.0.1:0", "urcap")
    assert t("schunk+http://h:80", {"http": "tcp"}) == ("schunk+tcp://h:80", "http")
    assert t("tcp://h:1", {"urcap": "tcp"}) == ("tcp://h:1", None)
    assert t("pty", {"urcap": "tcp"}) == ("pty", None)


def test_web_hosts_and_origins() -> None:
    assert [driver_urls.web_host(h) for h in ("[::1]:8000", "localhost:80", "10.0.0.2", "::1")] == [
        "::1",
        "localhost",
        "10.0.0.2",
        "::1",
    ]
    assert driver_urls.same_origin("http://127.0.0.1:8000", "127.0.0.1:8000")
    assert driver_urls.same_origin("http://h", "h:80") and driver_urls.same_origin("https://h", "h:443")
    assert not driver_urls.same_origin("http://evil:8000", "127.0.0.1:8000")
    assert not driver_urls.same_origin("file://", "h")
    assert driver_urls.web_target("/adi/data.json?inst=0x0040&count=1") == (
        "/adi/data.json",
        {"inst": "0x0040", "count": "1"},
    )
    assert driver_urls.web_fields("a&&b") == {}  # malformed: no fields, no exception


def test_queries_are_written_as_the_grammar_reads_them() -> None:
    url = driver_urls.with_query("stepfoc+can://virtual/ch?node=1,2&port=5", {"port": "5"})
    assert url == "stepfoc+can://virtual/ch?port=5"
    assert driver_urls.with_query("can://virtual/ch?node=1", {}) == "can://virtual/ch"
    serial = driver_urls.append_params("wsg+serial://socket://h:1?x=1?baudrate=9600", {"profile": "a b"})
    assert parse_url(serial).params == {"baudrate": "9600", "profile": "a b"}
    assert parse_url(serial).serial_port == "socket://h:1?x=1"
    assert driver_urls.append_params("sim://wsg50", {"profile": "wsg50"}) == "sim://wsg50?profile=wsg50"
    assert driver_urls.parse_query("", driver_urls.encode_query({"k": "a&b=c"})) == {"k": "a&b=c"}
