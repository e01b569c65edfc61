"""Servo tracking (issue 15): ``Gripper.servo`` following a sine, against the simulator's ideal path.

Targets follow a 0.25 Hz sine between 20 and 80 mm and are sent at 100 Hz for 20 simulated seconds (quick: 5)
to each simulator (WSG over loopback TCP, MSG over a python-can ``virtual`` bus), at time scale 1. The same
targets are also fed straight into a fresh copy of the simulator's pure model at exactly 10 ms intervals of
simulated time, with no library, thread or wire in between: that is the ideal path, the best the device
itself can do. Reported per simulator:

- lag: the time shift of the library-driven path behind the ideal path that fits it best;
- RMS error: between the library-driven path and the ideal path (both sampled in simulated time);
- CPU per target: this process's CPU in the threads that call ``servo`` and send (the caller inside
  ``servo()``, the servo thread, the driver's reader), per target received and per target sent; baseline: the
  device's ``servo.send`` primitive called synchronously at the same 100 Hz with targets far apart, so that
  every call goes on the wire (the wire commands alone, no latest-wins loop); the ratio compares servo's
  CPU per target received with that cost of putting every target on the wire synchronously;
- wire share: the targets that went on the wire (the rest were coalesced or needed no frame).

Target 12 (issue 21 §3) sends the same targets from a ``zenoh://`` client to a served gripper (``grippers
serve``'s Server, in this process so that the simulator's true path can be sampled; client and server talk
Zenoh over loopback TCP). Reported beside the local figures of the same run: the lag and RMS error against
the ideal path, and the RMS error against the ideal path taken 50 ms late (goal: at most 2 mm).
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from typing import Any

import grippers
from benchmarks.common import Result, thread_cpu_clock
from grippers.drivers.stepfoc.can_protocol import GripperCommand
from grippers.drivers.wsg.commands import Cmd, encode_request
from grippers.drivers.wsg.protocol import Packet
from grippers.servo import ServoTarget

RATE_HZ = 100.0
SINE_HZ = 0.25
LO_MM, HI_MM = 20.0, 80.0
SPEED = 0.1  # m/s: above the sine's peak velocity (47 mm/s), within both grippers' limits
LAG_LIMIT_S = 0.02  # goal: the library adds at most two control periods
RMS_LIMIT_MM = 1.0
CPU_RATIO_LIMIT = 2.0  # one thread hand-off per target (the servo thread) on top of the wire commands
REMOTE_LATE_S = 0.05  # issue 21 §3: the remote path against the ideal path taken this late
REMOTE_RMS_LIMIT_MM = 2.0
FAMILIES = (("wsg", "sim://wsg50?time_scale=1"), ("msg", "sim://msg-150?time_scale=1"))
_local_runs: dict[tuple[str, bool], dict[str, Any]] = {}  # (family, quick) -> local figures of this run


def target_mm(t: float) -> float:
    mid, amp = (LO_MM + HI_MM) / 2, (HI_MM - LO_MM) / 2
    return mid + amp * math.sin(2 * math.pi * SINE_HZ * t)


# -- the ideal paths: the pure models, commanded every 10 ms of simulated time ------------------------------


def _ideal_wsg(profile: Any, seconds: float, step: float) -> list[tuple[float, float]]:
    from grippers.backends.wsg import WsgBackend
    from grippers.backends.wsg_features import SERVO_TOLERANCE
    from grippers.settings import Settings

    server = WsgBackend().simulator(profile, Settings("bench", {}, {"time_scale": 1}))
    model = server.model
    server.close()  # only the model is wanted, advanced here in simulated time
    model.acceleration = model.max_accel  # as the library run sets it with 30h
    conn = model.connect()
    t = 0.0
    model.handle(Packet(Cmd.HOMING, encode_request(Cmd.HOMING, direction=0)), t, conn)
    t = _wsg_goto(model, conn, target_mm(0.0), t)
    samples, k, t0 = [], 0, t
    aim: float | None = None
    deferred: float | None = None
    tolerance = SERVO_TOLERANCE * 1000
    while k * (1 / RATE_HZ) < seconds:
        now = t0 + k / RATE_HZ
        offer = target_mm(k / RATE_HZ)
        for i in range(round(1 / RATE_HZ / step)):
            s = now + i * step
            model.advance(s)
            # The backend's policy, without a wire: re-target unless close to the running motion's target;
            # a put-off target is offered again when the motion has ended.
            if offer is None and deferred is not None and model._motion is None:
                offer, deferred = deferred, None
            if offer is not None:
                running = model._motion is not None
                if running and aim is not None and abs(offer - aim) <= tolerance:
                    deferred = offer
                else:
                    if running:
                        model.handle(Packet(Cmd.STOP), s, conn)
                    payload = encode_request(
                        Cmd.PREPOSITION, relative=False, stop_on_block=True, width=offer, speed=SPEED * 1000
                    )
                    model.handle(Packet(Cmd.PREPOSITION, payload), s, conn)
                    aim, deferred = offer, None
                offer = None
            samples.append((s - t0, model.position))
        k += 1
    return samples


def _wsg_goto(model: Any, conn: int, mm: float, t: float) -> float:
    for _ in range(10_000):
        t += 0.01
        model.advance(t)
        if model._motion is None:
            break
    payload = encode_request(
        Cmd.PREPOSITION, relative=False, stop_on_block=True, width=mm, speed=SPEED * 1000
    )
    model.handle(Packet(Cmd.PREPOSITION, payload), t, conn)
    for _ in range(10_000):
        t += 0.01
        model.advance(t)
        if model._motion is None:
            break
    return t


def _ideal_msg(g: Any, seconds: float, step: float) -> list[tuple[float, float]]:
    from grippers.backends.stepfoc import StepfocBackend

    model = StepfocBackend().sim_model(g.profile, 0, None)
    t = 0.0
    model.start_calibration(t)
    while not model.calibrated:
        t += 0.01
        model.advance(t)
    current = g.profile.maps.default_current_ma

    def command(mm: float, now: float) -> None:
        position = g.device.position_byte(mm / 1000)
        model.on_command(
            GripperCommand(position, g.device.speed_byte(SPEED), current, True, True, False), now
        )

    command(target_mm(0.0), t)
    for _ in range(2000):
        t += 0.01
        model.advance(t)
    samples, k, t0 = [], 0, t
    while k / RATE_HZ < seconds:
        now = t0 + k / RATE_HZ
        command(target_mm(k / RATE_HZ), now)
        for i in range(round(1 / RATE_HZ / step)):
            s = now + i * step
            model.advance(s)
            samples.append((s - t0, model.opening_mm))
        k += 1
    return samples


# -- the library-driven run -------------------------------------------------------------------------------


def _sampler(g: Any) -> Callable[[], tuple[float, float]]:
    """(simulated time, true opening in mm) read from the in-process simulator, no wire traffic."""
    server = g.simulator
    model = server.model
    from grippers.drivers.wsg.sim.model import WsgModel

    if isinstance(model, WsgModel):  # (the MSG's server has a lock attribute too since issue 19)

        def read_wsg() -> tuple[float, float]:
            with server.lock:
                now = server.clock.now()
                m = model._motion
                return now, (m.profile.position(now) if m is not None else model._x)

        return read_wsg

    def read_msg() -> tuple[float, float]:
        with server._lock:
            now = server.clock.now()
            model.advance(now)
            return now, model.opening_mm

    return read_msg


def _threads_cpu(g: Any, servo: bool = True, caller: bool = True) -> Callable[[], float]:
    """CPU seconds of the calling thread, the servo thread and the driver's reader (not the simulator's)."""
    names = ("grippers-servo", "reader") if servo else ("reader",)
    idents = [threading.get_ident()] * caller + [
        t.ident
        for t in threading.enumerate()
        if t.ident and any(n in t.name for n in names) and "sim" not in t.name.lower()
    ]
    clocks = [thread_cpu_clock(i) for i in idents]
    return lambda: sum(c() for c in clocks)


def _drive(url: str, seconds: float) -> dict[str, Any]:
    with grippers.open(url) as g:
        g.home()
        if hasattr(g.driver, "set_acceleration"):  # WSG: re-targeting restarts from rest; accelerate hard
            g.driver.set_acceleration(g.driver.system_limits().max_acceleration)
        g.move(target_mm(0.0) / 1000, SPEED)
        sample = _sampler(g)
        g.servo(target_mm(0.0) / 1000, SPEED)  # starts the servo thread before the CPU clocks are read
        g.servo_flush(2.0)
        others = _threads_cpu(g, caller=False)
        samples: list[tuple[float, float]] = []
        n = round(seconds * RATE_HZ)
        c0, w0, caller = others(), time.perf_counter(), 0.0
        t0 = sample()[0]
        for k in range(n):
            due = w0 + k / RATE_HZ
            while (delay := due - time.perf_counter()) > 0:
                time.sleep(delay)
            a = time.thread_time()
            g.servo(target_mm(k / RATE_HZ) / 1000, SPEED)
            caller += time.thread_time() - a
            now, mm = sample()
            samples.append((now - t0, mm))
            if k + 1 < n:  # one more sample half-way to the next target
                while (delay := due + 0.5 / RATE_HZ - time.perf_counter()) > 0:
                    time.sleep(delay)
                now, mm = sample()
                samples.append((now - t0, mm))
        g.servo_flush(2.0)
        cpu_used = others() - c0 + caller
        stats = g.servo_stats
        g._servo.end(stop_device=False)  # its thread's CPU clock is not read any more
        g.stop()
        # Baseline: the backend's primitive, called synchronously, for as many targets.
        # Paced at the same 100 Hz (a loop that sleeps between calls runs colder than a tight one).
        base_n = min(n, 300)
        cpu = _threads_cpu(g, servo=False)
        c1, w1 = cpu(), time.perf_counter()
        for k in range(base_n):
            while (delay := w1 + k / RATE_HZ - time.perf_counter()) > 0:
                time.sleep(delay)
            # far apart, so that every call goes on the wire (WSG: STOP + 21h; MSG: one 61)
            g.device.servo.send(ServoTarget((30.0 + 30.0 * (k % 2)) / 1000, SPEED, None))
        base_cpu = cpu() - c1
        g.stop()
        return {
            "gripper": g,
            "samples": samples,
            "cpu": cpu_used / n,
            "base_cpu": base_cpu / base_n,
            "stats": stats,
            "n": n,
        }


def _interp(path: list[tuple[float, float]], t: float) -> float:
    step = path[1][0] - path[0][0]
    i = min(max(int(t / step), 0), len(path) - 2)
    (ta, a), (tb, b) = path[i], path[i + 1]
    return a + (b - a) * (t - ta) / (tb - ta)


def _fit(samples: list[tuple[float, float]], ideal: list[tuple[float, float]]) -> tuple[float, float, float]:
    """(best lag in s, RMS error at that lag, RMS error at zero lag), in mm, skipping the first second.
    ``ideal`` must be sampled on a regular grid."""
    use = [(t, mm) for t, mm in samples if 1.0 <= t <= ideal[-1][0] - 0.2]

    def rms(lag: float) -> float:
        return math.sqrt(sum((mm - _interp(ideal, t - lag)) ** 2 for t, mm in use) / len(use))

    coarse = min((rms(lag / 100), lag / 100) for lag in range(0, 41))  # 0..400 ms in 10 ms steps
    centre = round(coarse[1] * 2000)
    best = min((rms(lag / 2000), lag / 2000) for lag in range(max(0, centre - 20), centre + 21))  # 0.5 ms
    return best[1], best[0], rms(0.0)


def _ideal(name: str, g: Any, seconds: float, step: float) -> list[tuple[float, float]]:
    if name == "wsg":
        return _ideal_wsg(g.profile, seconds + 1, step)
    return _ideal_msg(g, seconds + 1, step)


def _rms_at(samples: list[tuple[float, float]], ideal: list[tuple[float, float]], lag: float) -> float:
    use = [(t, mm) for t, mm in samples if 1.0 <= t <= ideal[-1][0] - 0.2]
    return math.sqrt(sum((mm - _interp(ideal, t - lag)) ** 2 for t, mm in use) / len(use))


def _drive_remote(url: str, seconds: float) -> dict[str, Any]:
    """The local drive's loop, from a zenoh:// client to a served gripper; the true path is sampled from
    the served simulator."""
    from grippers.remote.server import Server

    local = grippers.open(url)
    server = Server({"bench": local}, listen=["tcp/127.0.0.1:0"], rate=50.0)
    server.start()
    try:
        with grippers.open(server.url("bench")) as g:
            g.home()
            if hasattr(local.driver, "set_acceleration"):  # as the local run: re-targeting from rest
                local.driver.set_acceleration(local.driver.system_limits().max_acceleration)
            g.move(target_mm(0.0) / 1000, SPEED)
            sample = _sampler(local)
            g.servo(target_mm(0.0) / 1000, SPEED)
            g.servo_flush(2.0)
            samples: list[tuple[float, float]] = []
            n = round(seconds * RATE_HZ)
            w0 = time.perf_counter()
            t0 = sample()[0]
            for k in range(n):
                due = w0 + k / RATE_HZ
                while (delay := due - time.perf_counter()) > 0:
                    time.sleep(delay)
                g.servo(target_mm(k / RATE_HZ) / 1000, SPEED)
                now, mm = sample()
                samples.append((now - t0, mm))
                if k + 1 < n:
                    while (delay := due + 0.5 / RATE_HZ - time.perf_counter()) > 0:
                        time.sleep(delay)
                    now, mm = sample()
                    samples.append((now - t0, mm))
            g.servo_flush(2.0)
            stats = g.servo_stats
            served_stats = local.servo_stats
            g.stop()
            return {"gripper": local, "samples": samples, "stats": stats, "served": served_stats, "n": n}
    finally:
        server.close()  # closes the served gripper too


def run_remote(quick: bool) -> list[Result]:
    """Target 12: servo from a zenoh:// client, beside the local figures of the same run (target 11's, or
    measured here when 11 did not run)."""
    seconds = 5.0 if quick else 20.0
    step = 0.001
    results = []
    for name, url in FAMILIES:
        local = _local_runs.get((name, quick))
        if local is None:
            _run_family(name, url, seconds, quick)
            local = _local_runs[(name, quick)]
        got = _drive_remote(url, seconds)
        ideal = _ideal(name, got["gripper"], seconds, step)
        lag, rms_lag, rms0 = _fit(got["samples"], ideal)
        late = _rms_at(got["samples"], ideal, REMOTE_LATE_S)
        stats, served = got["stats"], got["served"]
        passed = late <= REMOTE_RMS_LIMIT_MM
        results.append(
            Result(
                f"12 servo {name} over zenoh:// (0.25 Hz sine @100 Hz)",
                f"lag {lag * 1000:.1f} ms, RMS {rms0:.2f} mm; {late:.2f} mm vs ideal 50 ms late",
                f"local: lag {local['lag'] * 1000:.1f} ms, RMS {local['rms0']:.2f} mm",
                f"lag {(lag - local['lag']) * 1000:+.1f} ms",
                f"RMS <= {REMOTE_RMS_LIMIT_MM:g} mm vs the ideal path {REMOTE_LATE_S * 1000:.0f} ms late",
                passed,
                [
                    f"client: {stats.received} targets, {stats.sent} queries to the server, "
                    f"{stats.coalesced} coalesced, {stats.failed} failed; served gripper: "
                    f"{served.received if served else 0} targets, {served.sent if served else 0} on the wire",
                    f"RMS against the ideal path at the best lag {rms_lag:.2f} mm",
                ],
            )
        )
    return results


def _run_family(name: str, url: str, seconds: float, quick: bool) -> Result:
    got = _drive(url, seconds)
    g = got["gripper"]
    step = 0.001
    ideal = _ideal(name, g, seconds, step)
    lag, rms_lag, rms0 = _fit(got["samples"], ideal)
    _local_runs[(name, quick)] = {"lag": lag, "rms0": rms0}
    sine = [(i * step, target_mm(i * step)) for i in range(round((seconds + 1) / step))]
    lag_sine, _, rms_sine = _fit(got["samples"], sine)
    ideal_lag, _, ideal_rms = _fit(ideal, sine)
    stats = got["stats"]
    share = stats.sent / stats.received
    per_sent = got["cpu"] * stats.received / max(stats.sent, 1)
    ratio = got["cpu"] / got["base_cpu"]
    passed = lag <= LAG_LIMIT_S and rms0 <= RMS_LIMIT_MM and ratio <= CPU_RATIO_LIMIT
    return Result(
        f"11 servo {name} (0.25 Hz sine @100 Hz)",
        f"lag {lag * 1000:.1f} ms, RMS {rms0:.2f} mm; {got['cpu'] * 1e6:.0f} us/target",
        f"ideal path; {got['base_cpu'] * 1e6:.0f} us/target sent sync",
        f"CPU {ratio:.2f}x",
        f"lag <= {LAG_LIMIT_S * 1000:.0f} ms, RMS <= {RMS_LIMIT_MM:g} mm, CPU <= {CPU_RATIO_LIMIT:g}x",
        passed,
        [
            f"{stats.received} targets in {seconds:g} simulated s: {stats.sent} on the wire "
            f"({share:.1%}), {stats.coalesced} coalesced, {stats.unchanged} needed no frame, "
            f"{stats.failed} failed; CPU {per_sent * 1e6:.0f} us per target that went on the wire",
            f"against the sine itself: lag {lag_sine * 1000:.0f} ms, RMS {rms_sine:.2f} mm "
            f"(the ideal path: lag {ideal_lag * 1000:.0f} ms, RMS {ideal_rms:.2f} mm; "
            "the device's own "
            f"dynamics); RMS against the ideal path at the best lag {rms_lag:.2f} mm",
        ],
    )


def run(quick: bool) -> list[Result]:
    seconds = 5.0 if quick else 20.0
    return [_run_family(name, url, seconds, quick) for name, url in FAMILIES]
