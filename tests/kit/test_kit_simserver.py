"""The simulator kit: a byte-level device model served on a pty and on TCP, its clock, and every fault hook
as a client of the kit's links sees it."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator

import pytest

from grippers import ConnectionLost, GripperTimeout
from grippers.kit import ByteLink, FaultHooks, SerialLink, SimServer, TcpLink

SHORT = 0.1  # the client's wait where no answer must come (the device dropped or stalled it)
LONG = 10.0  # the client's wait where an answer must come: ends as soon as it does


class Counter:
    """A device model: each 4-byte request is answered by 4 bytes, the request reversed; ``seen`` counts
    requests, ``times`` records the simulated time each was answered at and ``advanced`` the clock's ticks."""

    def __init__(self) -> None:
        self.seen = 0
        self.times: list[float] = []
        self.advanced: list[float] = []
        self.disconnects = 0

    def advance(self, now: float) -> None:
        self.advanced.append(now)


class CounterSession:
    def __init__(self, model: Counter) -> None:
        self.model, self.buf = model, b""

    def feed(self, data: bytes, now: float) -> list[bytes]:
        self.buf += data
        out = []
        while len(self.buf) >= 4:
            request, self.buf = self.buf[:4], self.buf[4:]
            if request == b"boom":
                raise RuntimeError("the model broke")
            self.model.seen += 1
            self.model.times.append(now)
            out.append(request[::-1])
        return out

    def closed(self, now: float) -> None:
        self.model.disconnects += 1


@pytest.fixture(params=["pty", "tcp"])
def served(request: pytest.FixtureRequest) -> Iterator[tuple[SimServer, Counter, ByteLink]]:
    model = Counter()
    listen = "pty" if request.param == "pty" else "tcp://127.0.0.1:0"
    server = SimServer(listen, lambda: CounterSession(model), family="demo", advance=model.advance)
    link: ByteLink
    if request.param == "pty":
        assert server.url == f"demo+serial://{server.path}"
        link = SerialLink(str(server.path), device="demo")
    else:
        assert server.url == f"demo+tcp://127.0.0.1:{server.port}"
        link = TcpLink("127.0.0.1", int(server.port or 0), device="demo")
    yield server, model, link
    link.close()
    server.close()
    server.close()  # idempotent


def ask(link: ByteLink, request: bytes, wait: float = LONG) -> bytes:
    link.write(request, command="ask")
    return link.read_exactly(4, time.monotonic() + wait, command="ask")


def until(what: str, predicate: Callable[[], bool], bound: float = LONG) -> None:
    deadline = time.monotonic() + bound
    while not predicate():
        assert time.monotonic() < deadline, f"{what}: not within {bound:g} s"
        time.sleep(0.01)


def test_the_model_answers_through_the_server(served: tuple[SimServer, Counter, ByteLink]) -> None:
    server, model, link = served
    assert ask(link, b"abcd") == b"dcba" and model.seen == 1
    assert server.error is None


def test_dropped_corrupted_truncated_duplicated_and_garbled_replies(
    served: tuple[SimServer, Counter, ByteLink],
) -> None:
    server, model, link = served
    server.faults.drop_replies(1)
    with pytest.raises(GripperTimeout):
        ask(link, b"abcd", SHORT)
    assert model.seen == 1  # the device took the request and kept its reply
    assert ask(link, b"wxyz") == b"zyxw"

    server.faults.corrupt_replies(1)
    assert ask(link, b"abcd") == b"dcb" + bytes([ord("a") ^ 0xFF])

    server.faults.truncate_replies(1)
    link.write(b"abcd")
    with pytest.raises(GripperTimeout, match="got 2"):
        link.read_exactly(4, time.monotonic() + SHORT)
    assert link.discard_input() == 2  # the half reply, read and kept by the timed-out read

    server.faults.duplicate_replies(1)
    assert ask(link, b"1234") == b"4321" and link.read_exactly(4, time.monotonic() + LONG) == b"4321"

    server.faults.send_garbage(b"\xff\xfe")
    link.write(b"abcd")
    assert link.read_exactly(6, time.monotonic() + LONG) == b"\xff\xfedcba"


def test_silence_and_a_stall_that_ends_by_itself(served: tuple[SimServer, Counter, ByteLink]) -> None:
    server, model, link = served
    server.faults.silent = True
    with pytest.raises(GripperTimeout):
        ask(link, b"abcd", SHORT)
    server.faults.silent = False
    assert ask(link, b"abcd") == b"dcba"

    server.faults.stall(60.0)
    assert server.faults.silent
    with pytest.raises(GripperTimeout):
        ask(link, b"abcd", SHORT)
    server.faults.stall(0.2)  # a shorter stall: the device answers again by itself once it is over
    until("the stall over", lambda: not server.faults.silent)
    link.discard_input()
    assert ask(link, b"wxyz") == b"zyxw"


def test_delayed_replies_come_late(served: tuple[SimServer, Counter, ByteLink]) -> None:
    server, _, link = served
    server.faults.delay_replies(0.3)
    started = time.monotonic()
    assert ask(link, b"abcd") == b"dcba"
    assert time.monotonic() - started >= 0.3


def test_close_is_seen_as_a_lost_link(served: tuple[SimServer, Counter, ByteLink]) -> None:
    server, model, link = served
    assert ask(link, b"abcd") == b"dcba"
    server.faults.request_close()
    if server.port is None:  # a pty has no connection to drop: the line stays up (docs/backend-kit.md)
        until("the request taken", lambda: not server.faults.close_requested.is_set())
        assert ask(link, b"abcd") == b"dcba" and not link.lost
        return
    with pytest.raises(ConnectionLost):
        link.read_exactly(1, time.monotonic() + LONG)
    assert link.lost
    until("the session told of its closed connection", lambda: model.disconnects == 1)
    with TcpLink("127.0.0.1", int(server.port), device="again") as fresh:  # the device serves a new client
        assert ask(fresh, b"abcd") == b"dcba"


def test_the_clock_held_and_stepped(served: tuple[SimServer, Counter, ByteLink]) -> None:
    server, model, link = served
    server.pause()
    held = server.now()
    ask(link, b"abcd")
    ask(link, b"abcd")
    assert model.times[-2:] == [held, held]  # a held device answers at one instant
    server.step(2.5)
    assert model.advanced[-1] == pytest.approx(held + 2.5)  # step() moves the model on with the clock
    ask(link, b"abcd")
    assert model.times[-1] == pytest.approx(held + 2.5)
    server.resume()
    until("the clock running again", lambda: server.now() > held + 2.5)


def test_an_error_in_the_model_is_kept_for_the_fixture(served: tuple[SimServer, Counter, ByteLink]) -> None:
    server, _, link = served
    link.write(b"boom")
    until("the server's error", lambda: server.error is not None)
    assert isinstance(server.error, RuntimeError)
    server.error = None  # the fixture would fail the test: this one expects it


def test_fault_hooks_clear() -> None:
    hooks = FaultHooks()
    hooks.drop_replies(2)
    hooks.stall(60)
    hooks.silent = True
    hooks.send_garbage(b"x")
    hooks.clear()
    assert hooks.take() is None and not hooks.silent and hooks.take_garbage() == b""


def test_a_bad_listen_address_is_refused() -> None:
    from grippers import URLError

    with pytest.raises(URLError):
        SimServer("demo+udp://127.0.0.1:0", lambda: CounterSession(Counter()), family="demo")
