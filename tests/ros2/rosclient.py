"""An independent rclpy client for the node's tests, and the node run as a subprocess (`grippers ros2`).

Nothing here uses grippers.ros2: the tests see the node only through ROS 2, as a user's program would.
"""

from __future__ import annotations

import os
import queue
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

import rclpy
from rclpy.action import ActionClient
from rclpy.executors import MultiThreadedExecutor

WAIT = 60.0  # s: an upper bound for anything on a loaded machine, never a speed expectation
ASKS = 3  # requests within WAIT before a missing answer fails a test (RosClient.answered)


class CliProcess:
    """`python -m grippers ARGS...` with its output collected; ready once stdout shows ``ready`` in a line."""

    def __init__(self, *args: str, ready: str) -> None:
        env = {**os.environ, "PYTHONUNBUFFERED": "1"}
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "grippers", *args],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=env,
        )
        self.lines: queue.Queue[str] = queue.Queue()
        self.stdout: list[str] = []
        self.stderr: list[str] = []
        threading.Thread(target=self._read, args=(self.proc.stdout, self.stdout, True), daemon=True).start()
        threading.Thread(target=self._read, args=(self.proc.stderr, self.stderr, False), daemon=True).start()
        deadline = time.monotonic() + WAIT
        while True:
            try:
                line = self.lines.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                self.terminate()
                raise AssertionError(f"{args[0]} not ready within {WAIT} s: {self.output()}") from None
            if ready in line:
                self.ready_line = line.strip()
                break
            if not line:  # the node ended before it was ready
                self.terminate()
                raise AssertionError(f"{args[0]} ended before it was ready: {self.output()}")

    def _read(self, stream: Any, into: list[str], announce: bool) -> None:
        for line in stream:
            into.append(line)
            if announce:
                self.lines.put(line)
        if announce:
            self.lines.put("")

    def output(self) -> str:
        return "".join(self.stdout) + "".join(self.stderr)

    def alive(self) -> bool:
        return self.proc.poll() is None

    def terminate(self, sig: int = signal.SIGTERM, timeout: float = WAIT) -> int:
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
        try:
            return self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait(10)
            raise AssertionError(f"node did not end within {timeout} s of signal {sig}") from None


def node_process(url: str, *args: str) -> CliProcess:
    """`grippers ros2 URL ARGS...`, once its node is up."""
    return CliProcess("ros2", url, *args, ready=" ready ")


def serve_process(name: str, url: str) -> tuple[CliProcess, str]:
    """`grippers serve NAME=URL` on a loopback port the system picks; returns it and its zenoh:// URL."""
    proc = CliProcess("serve", f"{name}={url}", "--listen", "tcp/127.0.0.1:0", ready=" serving at ")
    return proc, proc.ready_line.rsplit(" serving at ", 1)[1]


class RosClient:
    """A client node of its own context, spun in a background thread."""

    def __init__(self, name: str) -> None:
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node(name, context=self.context)
        self.executor = MultiThreadedExecutor(num_threads=4, context=self.context)
        self.executor.add_node(self.node)
        self._thread = threading.Thread(target=self.executor.spin, daemon=True)
        self._thread.start()
        self._actions: dict[str, ActionClient] = {}

    def close(self) -> None:
        for client in self._actions.values():
            client.destroy()
        self.executor.shutdown(timeout_sec=10)
        self._thread.join(10)
        self.node.destroy_node()
        rclpy.shutdown(context=self.context)

    @staticmethod
    def wait(future: Any, timeout: float = WAIT) -> Any:
        done = threading.Event()
        future.add_done_callback(lambda _f: done.set())
        assert done.wait(timeout), f"no answer within {timeout} s"
        return future.result()

    def action(self, action_type: Any, name: str) -> ActionClient:
        if name not in self._actions:
            client = ActionClient(self.node, action_type, name)
            assert client.wait_for_server(timeout_sec=WAIT), f"action server {name} not found"
            self._actions[name] = client
        return self._actions[name]

    @classmethod
    def answered(cls, ask: Callable[[], Any], what: str, timeout: float = WAIT, tries: int = ASKS) -> Any:
        """``ask()`` (a request: a future of its answer) again when no answer came within ``timeout / tries``.

        Why: the first request on a new service or action client can go unanswered. ``wait_for_server`` and
        ``wait_for_service`` return once the *client's* readers matched the server's writers, and with Fast
        DDS the server's reply writer may not have matched the client's reply reader yet: the reply is then
        never delivered (a known ROS 2 race, seen here only on a loaded machine, where discovery is slow).
        Asked again, the same request is answered. Only idempotent requests go through here, and a goal: a
        goal sent again supersedes the lost copy if that one was taken after all (newer goal wins, the
        node's documented rule), so the answer is the one of the goal the test meant.
        """
        per_try = timeout / tries
        for _ in range(tries):
            future = ask()
            done = threading.Event()
            future.add_done_callback(lambda _f, done=done: done.set())
            if done.wait(per_try):
                return future.result()
            future.cancel()
        raise AssertionError(f"{what}: no answer within {timeout} s ({tries} requests)")

    def send(self, action_type: Any, name: str, goal: Any, feedback: list[Any] | None = None) -> Any:
        """Send a goal; returns its goal handle (``.accepted`` tells whether the node took it)."""
        client = self.action(action_type, name)
        callback = None if feedback is None else (lambda msg: feedback.append(msg.feedback))
        ask = lambda: client.send_goal_async(goal, feedback_callback=callback)  # noqa: E731
        return self.answered(ask, f"goal to {name}")

    def result(self, goal_handle: Any, timeout: float = WAIT) -> tuple[int, Any]:
        answer = self.answered(goal_handle.get_result_async, "goal result", timeout)
        return answer.status, answer.result

    def call(self, srv_type: Any, name: str, timeout: float = WAIT, request: Any = None) -> Any:
        client = self.node.create_client(srv_type, name)
        try:
            assert client.wait_for_service(timeout_sec=WAIT), f"service {name} not found"
            return self.answered(lambda: client.call_async(request or srv_type.Request()), name, timeout)
        finally:
            self.node.destroy_client(client)

    # rclpy's parameter services (what `ros2 param list/get/set` call)
    def list_parameters(self, node: str) -> list[str]:
        from rcl_interfaces.srv import ListParameters

        return list(self.call(ListParameters, f"{node}/list_parameters").result.names)

    def get_parameters(self, node: str, *names: str) -> list[Any]:
        from rcl_interfaces.srv import GetParameters
        from rclpy.parameter import parameter_value_to_python

        answer = self.call(
            GetParameters, f"{node}/get_parameters", request=GetParameters.Request(names=list(names))
        )
        return [parameter_value_to_python(v) for v in answer.values]

    def set_parameters(self, node: str, **values: Any) -> list[Any]:
        """Set parameters; returns the SetParametersResult of each (``.successful``, ``.reason``)."""
        from rcl_interfaces.srv import SetParameters
        from rclpy.parameter import Parameter

        params = [Parameter(k, value=v).to_parameter_msg() for k, v in values.items()]
        answer = self.call(
            SetParameters, f"{node}/set_parameters", request=SetParameters.Request(parameters=params)
        )
        return list(answer.results)

    def subscribe(self, msg_type: Any, topic: str) -> queue.Queue[Any]:
        received: queue.Queue[Any] = queue.Queue()
        self.node.create_subscription(msg_type, topic, received.put, 50)
        return received


def wait_until(predicate: Any, timeout: float = WAIT, what: str = "condition") -> None:
    """Poll ``predicate`` (bounded); for conditions a test can only observe, never for pacing."""
    deadline = time.monotonic() + timeout
    while not predicate():
        assert time.monotonic() < deadline, f"{what} not met within {timeout} s"
        time.sleep(0.02)
