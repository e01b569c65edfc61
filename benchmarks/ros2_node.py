"""Target 15: a GripperCommand goal through `grippers ros2`, against a bare rclpy action server (issue 34 §6).

The goal asks for the width the jaws already have (nothing to move), so the figure is what the node adds to
ROS's own action round trip: checking the goal against the limits, reading the state, deciding, answering.
The baseline is a bare rclpy GripperCommand server that succeeds at once, in the same run and the same ROS
domain; goals go to the two alternately in slices, so machine noise hits both sides alike. Beside it: the
p99 of both, and the p99 of joint_states' period jitter (|period - 10 ms|, from the header stamps) at 100 Hz.

rclpy is not a dependency of grippers: the measurement runs in a child process inside the environment
``scripts/setup-ros2.sh`` builds (the one the ROS 2 tests use), with a ROS_DOMAIN_ID of its own.
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path
from typing import Any

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.common import REPO, Result

GOAL = 1.5  # the node's median send-to-result at most this many times the bare server's

BARE_SERVER = textwrap.dedent(
    """
    import sys
    import rclpy
    from control_msgs.action import GripperCommand
    from rclpy.action import ActionServer
    from rclpy.executors import MultiThreadedExecutor, SingleThreadedExecutor

    def execute(goal_handle):
        goal_handle.succeed()
        result = GripperCommand.Result()
        result.position = goal_handle.request.command.position
        result.reached_goal = True
        return result

    threads = int(sys.argv[1])  # 0: rclpy.spin's single-threaded executor
    rclpy.init()
    node = rclpy.create_node(sys.argv[2])
    server = ActionServer(node, GripperCommand, "~/gripper_cmd", execute)
    executor = MultiThreadedExecutor(num_threads=threads) if threads else SingleThreadedExecutor()
    print("bare ready", flush=True)
    try:
        rclpy.spin(node, executor=executor)
    except (KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
        pass
    finally:
        server.destroy()
        node.destroy_node()
        rclpy.try_shutdown()
    """
)


def _p99(values: list[float]) -> float:
    return sorted(values)[max(0, int(len(values) * 0.99) - 1)]


def _wait_line(proc: subprocess.Popen[str], word: str, bound: float = 60.0) -> None:
    assert proc.stdout is not None
    deadline = time.monotonic() + bound
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        if not line:
            break
        if word in line:
            return
    proc.kill()
    raise RuntimeError(f"{proc.args} did not say {word!r}: {proc.stderr.read() if proc.stderr else ''}")


def _stop(proc: subprocess.Popen[str]) -> None:
    if proc.poll() is None:
        proc.send_signal(2)
        try:
            proc.wait(15)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(5)


def _costs(url: str, n: int) -> dict[str, float]:
    """The node's steps, timed on a gripper of their own: what a goal to the current width spends."""
    import grippers

    out: dict[str, list[float]] = {"check": [], "state": [], "move": []}
    with grippers.open(url) as g:
        g.home()
        width = g.state().width
        for _ in range(n):
            t0 = time.perf_counter()
            g.check(width, None, None, command="bench")
            t1 = time.perf_counter()
            g.state()
            t2 = time.perf_counter()
            g.move(width)
            t3 = time.perf_counter()
            out["check"].append(t1 - t0)
            out["state"].append(t2 - t1)
            out["move"].append(t3 - t2)
    return {k: statistics.median(v) for k, v in out.items()}


def child(goals: int, sessions: int) -> dict[str, Any]:
    """Runs inside the ROS 2 environment; returns the figures as a dict (printed as JSON by main)."""
    import rclpy
    from control_msgs.action import GripperCommand
    from rclpy.action import ActionClient
    from rclpy.executors import MultiThreadedExecutor
    from sensor_msgs.msg import JointState
    from std_srvs.srv import Trigger

    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    py = sys.executable
    node = subprocess.Popen(
        [py, "-m", "grippers", "ros2", "sim://wsg50", "--name", "bench_gripper", "--rate", "100"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        cwd=REPO,
    )
    bares = [
        subprocess.Popen(
            [py, "-c", BARE_SERVER, threads, name],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=env,
        )
        for threads, name in (("0", "bare_gripper"), ("8", "bare_mt_gripper"))
    ]
    rclpy.init()
    client = rclpy.create_node("bench_client")
    executor = MultiThreadedExecutor(num_threads=2)
    executor.add_node(client)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    try:
        _wait_line(node, " ready ")
        for bare in bares:
            _wait_line(bare, "bare ready")
        spinner.start()
        stamps: list[float] = []  # header stamps of joint_states (s)
        widths: list[float] = []

        def on_joint_state(m: Any) -> None:
            stamps.append(m.header.stamp.sec + m.header.stamp.nanosec * 1e-9)
            widths.append(m.position[0])

        client.create_subscription(JointState, "joint_states", on_joint_state, 100)
        home = client.create_client(Trigger, "/bench_gripper/home")
        assert home.wait_for_service(timeout_sec=60)
        done = threading.Event()
        home.call_async(Trigger.Request()).add_done_callback(lambda _f: done.set())
        assert done.wait(60), "home did not answer"
        servers = {
            "node": ActionClient(client, GripperCommand, "/bench_gripper/gripper_cmd"),
            "bare": ActionClient(client, GripperCommand, "/bare_gripper/gripper_cmd"),
            "bare_mt": ActionClient(client, GripperCommand, "/bare_mt_gripper/gripper_cmd"),
        }
        for c in servers.values():
            assert c.wait_for_server(timeout_sec=60)
        # the width the jaws have, as the node publishes it after homing
        widths.clear()
        deadline = time.monotonic() + 60
        while not widths and time.monotonic() < deadline:
            time.sleep(0.01)
        width = widths[-1]

        def one(c: ActionClient) -> tuple[float, bool]:
            goal = GripperCommand.Goal()
            goal.command.position = width
            ended = threading.Event()
            box: list[Any] = []

            def on_result(f: Any) -> None:
                box.append(f.result())
                ended.set()

            def on_goal(f: Any) -> None:
                handle = f.result()
                if not handle.accepted:
                    ended.set()
                    return
                handle.get_result_async().add_done_callback(on_result)

            # Asked again when no answer came in 10 s: Fast DDS may lose the first reply to a new client
            # (the server's reply writer not yet matched; tests/ros2/rosclient.py `answered`). A goal asked
            # again is not timed: it says what the machine's discovery cost, not what the node does.
            for attempt in range(3):
                t0 = time.perf_counter()
                c.send_goal_async(goal).add_done_callback(on_goal)
                if ended.wait(10):
                    took = time.perf_counter() - t0
                    return (took if attempt == 0 else float("nan")), bool(box) and box[0].status == 4
            raise AssertionError("no result within 30 s (3 goals)")

        times: dict[str, list[list[float]]] = {name: [] for name in servers}
        failed = 0
        for _ in range(5):  # warm-up: discovery, first allocations
            for c in servers.values():
                one(c)
        stamps.clear()
        t_js = time.monotonic()
        for _ in range(sessions):
            for name in servers:
                times[name].append([])
            for _ in range(goals):  # goal by goal, so the machine's noise falls on every server alike
                for name, c in servers.items():
                    took, ok = one(c)
                    if took == took:  # nan: the goal had to be asked again (not timed, see one())
                        times[name][-1].append(took)
                    failed += not ok
        js = list(stamps)
        js_span = time.monotonic() - t_js
        periods = [b - a for a, b in zip(js, js[1:], strict=False)]
        jitter = [abs(p - 0.01) for p in periods]
        return {
            "node": times["node"],
            "bare": times["bare"],
            "bare_mt": times["bare_mt"],
            "failed": failed,
            "jitter_p99": _p99(jitter) if jitter else float("nan"),
            "js_rate": len(js) / js_span if js_span > 0 else 0.0,
            "costs": _costs("sim://wsg50", 50),
        }
    finally:
        for c in locals().get("servers", {}).values():
            c.destroy()
        executor.shutdown(timeout_sec=5)
        client.destroy_node()
        rclpy.try_shutdown()
        _stop(node)
        for bare in bares:
            _stop(bare)


def run(quick: bool) -> list[Result]:
    goals, sessions = (100, 1) if quick else (200, 3)
    env_dir = subprocess.run(
        [str(REPO / "scripts" / "setup-ros2.sh"), "--print-dir"], capture_output=True, text=True, check=True
    ).stdout.strip()
    script = (
        f'. "{env_dir}/env.sh" && export ROS_DOMAIN_ID={os.getpid() % 100 + 1} '
        "ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST && "
        f'exec "$GRIPPERS_ROS2_PYTHON" -m benchmarks.ros2_node {goals} {sessions}'
    )
    proc = subprocess.run(["bash", "-c", script], capture_output=True, text=True, cwd=REPO, timeout=900)
    if proc.returncode != 0:
        raise RuntimeError(f"the ROS 2 benchmark failed: {proc.stderr[-3000:]}")
    got = json.loads(proc.stdout.strip().splitlines()[-1])
    # the ratio: the median of the sessions' ratios (as target 13), so one burst of load elsewhere on the
    # machine moves one session, not the figure; medians and p99s over every goal
    ratio = statistics.median(
        statistics.median(n) / statistics.median(b) for n, b in zip(got["node"], got["bare"], strict=True)
    )
    every = {name: [t for session in got[name] for t in session] for name in ("node", "bare", "bare_mt")}
    node, bare, bare_mt = (statistics.median(every[name]) for name in ("node", "bare", "bare_mt"))
    ratios = ", ".join(
        f"{statistics.median(n) / statistics.median(b):.2f}x"
        for n, b in zip(got["node"], got["bare"], strict=True)
    )
    costs = got["costs"]
    return [
        Result(
            "15 ROS 2 goal send-to-result",
            f"{node * 1e3:.2f} ms",
            f"{bare * 1e3:.2f} ms",
            f"{ratio:.2f}x",
            f"<= {GOAL:g}x",
            ratio <= GOAL and got["failed"] == 0,
            [
                f"{sessions} session(s) of {goals} GripperCommand goals to the current width (sim://wsg50) "
                f"to each server, alternating goal by goal; ratio per session {ratios}; "
                f"{got['failed']} did not succeed",
                f"a bare server on a MultiThreadedExecutor (the node's kind): {bare_mt * 1e3:.2f} ms median, "
                f"p99 {_p99(every['bare_mt']) * 1e3:.2f} ms",
                f"p99: node {_p99(every['node']) * 1e3:.2f} ms, "
                f"bare rclpy server {_p99(every['bare']) * 1e3:.2f} ms",
                f"joint_states at --rate 100: {got['js_rate']:.1f} Hz received, period jitter p99 "
                f"{got['jitter_p99'] * 1e3:.2f} ms",
                "the node's steps (medians on a gripper of their own): "
                f"limit check {costs['check'] * 1e6:.0f} us, "
                f"state() {costs['state'] * 1e3:.2f} ms; a move to the current width, no longer sent, "
                f"{costs['move'] * 1e3:.2f} ms",
            ],
        )
    ]


if __name__ == "__main__":
    print(json.dumps(child(int(sys.argv[1]), int(sys.argv[2]))))
