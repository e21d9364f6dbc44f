"""Fault injection for trials through the nodes (docs/reliability.md, "Fault matrix").

:class:`FaultTrial` runs a lockstep trial with every node its own process
(:class:`excavation_bringup.launch.ProcessLauncher`, what ``ant-trial --processes`` runs) and
a watcher node in this process that listens on the same ROS domain: the tick (``/clock``),
every ``/diagnostics`` status, and with full perception the true and the mapped height
maps. A test kills a node (SIGKILL), restarts it, changes a node's parameters at runtime
(the synthetic sensors' fault knobs) and then reads what the system did from the watcher,
the simulator's result and the bag. A new row of the matrix is a few lines::

    with FaultTrial(tmp_path, steps=40) as trial:
        trial.wait_tick(5)
        trial.kill("blade_driver_1")
        trial.wait_tick(trial.tick + 3)
        trial.restart("blade_driver_1")
        result = trial.result()
    assert result["missed_blade_setpoints"]["1"] >= 1
"""

from __future__ import annotations

import os
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from conftest import next_domain

from excavation_bringup.deployment import Deployment
from excavation_bringup.graph import build
from excavation_bringup.launch import ProcessLauncher


@dataclass
class Status:
    """One ``/diagnostics`` status as the watcher heard it."""

    wall: float
    tick: int
    name: str
    level: int
    message: str
    values: dict[str, str] = field(default_factory=dict)


class Watcher:
    """An rclpy node on the trial's domain, spun in a background thread."""

    def __init__(self, domain: int, perception: str, continuous: bool = False) -> None:
        import rclpy
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node
        from rclpy.signals import SignalHandlerOptions
        from rosgraph_msgs.msg import Clock
        from sensor_msgs.msg import Image
        from std_msgs.msg import Header

        from excavation_common.ros import LATCHED

        self.context = Context()
        rclpy.init(
            context=self.context, domain_id=domain, signal_handler_options=SignalHandlerOptions.NO
        )
        self.node = Node("fault_watcher", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.lock = threading.Lock()
        self.tick = -1
        self.ticks_seen: list[int] = []
        self.statuses: list[Status] = []
        self.maps: dict[str, dict[tuple[int, int], np.ndarray]] = {"truth": {}, "mapped": {}}
        if continuous:  # the team tick's tick (sim time runs on between ticks)
            self.node.create_subscription(Header, "/team/tick", self.on_team_tick, 100)
        else:
            self.node.create_subscription(Clock, "/clock", self.on_clock, 100)
        self.node.create_subscription(DiagnosticArray, "/diagnostics", self.on_diagnostics, 100)
        if perception == "full":
            for kind, topic in (
                ("truth", "/truth/worksite/height_map"),
                ("mapped", "/worksite/height_map"),
            ):
                self.node.create_subscription(
                    Image, topic, lambda m, kind=kind: self.on_map(kind, m), LATCHED
                )
        self.thread = threading.Thread(target=self.spin, daemon=True)
        self.thread.start()

    def spin(self) -> None:
        """Spin until the context shuts down."""
        from rclpy.executors import ExternalShutdownException

        try:
            while self.context.ok():
                self.executor.spin_once(timeout_sec=0.05)
        except (ExternalShutdownException, RuntimeError):
            pass

    def on_clock(self, msg) -> None:
        """The simulator's tick (sim time, 1 s per tick)."""
        with self.lock:
            self.tick = int(msg.clock.sec)
            self.ticks_seen.append(self.tick)

    def on_team_tick(self, msg) -> None:
        """The continuous trial's tick (``/team/tick``, the tick in ``frame_id``)."""
        with self.lock:
            self.tick = int(msg.frame_id)
            self.ticks_seen.append(self.tick)

    def on_diagnostics(self, msg) -> None:
        """Keep every status."""
        with self.lock:
            for s in msg.status:
                values = {kv.key: kv.value for kv in s.values}
                level = int.from_bytes(s.level, "little") if isinstance(s.level, bytes) else s.level
                self.statuses.append(
                    Status(time.monotonic(), self.tick, s.name, int(level), s.message, values)
                )

    def on_map(self, kind: str, msg) -> None:
        """A height map (metres) by stamp."""
        from excavation_common.messages import image_to_grid

        grid = image_to_grid(msg, "32FC1", kind)
        with self.lock:
            self.maps[kind][(msg.header.stamp.sec, msg.header.stamp.nanosec)] = grid

    def close(self) -> None:
        """Stop spinning and shut the context down."""
        import rclpy

        rclpy.try_shutdown(context=self.context)
        self.thread.join(timeout=5.0)
        self.node.destroy_node()


class FaultTrial:
    """A process trial with a watcher; a context manager that stops everything at the end.

    Args:
        workdir: Logs, ``result.json``, the calibration (and bags, when asked).
        robots, steps, seed, controller, blueprint, command_timeout, blade_driver,
        perception, record: As ``ant-trial``'s options.
        start: Start every node now (else: change parameters with
            ``processes.set_params``, then ``processes.start()``).
        continuous: The continuous trial (``--drive continuous``): drive executors, the
            ``dynamics`` simulator and the team tick, whose ``/team/tick`` is the tick and
            whose ``result.json`` is :meth:`result`.
    """

    def __init__(
        self,
        workdir: Path,
        robots: int = 2,
        steps: int = 40,
        seed: int = 3,
        controller: str = "hand-coded",
        blueprint: str = "default:1",
        command_timeout: float = 5.0,
        blade_driver: bool = True,
        perception: str = "truth",
        record: str | None = None,
        start: bool = True,
        continuous: bool = False,
    ) -> None:
        os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
        self.domain = next_domain()
        self.spec = Deployment(
            controller,
            robots,
            steps,
            seed,
            blueprint,
            0,
            self.domain,
            command_timeout,
            600.0,
            blade_driver,
            record,
            perception,
            drive="continuous" if continuous else "grid",
            exact=True,  # ant-trial --drive continuous --no-slip
            processes=True,
        )
        self.processes = ProcessLauncher(build(self.spec, workdir))
        self.watcher = Watcher(self.domain, perception, continuous)
        self.started = time.monotonic()
        if start:
            self.processes.start()

    @property
    def tick(self) -> int:
        """The latest tick published (-1 before tick 0)."""
        return self.watcher.tick

    def wait_tick(self, tick: int, timeout: float = 240.0) -> int:
        """Wait until tick ``tick`` is published (or the simulator ends); returns the tick.

        Raises:
            TimeoutError: Not reached within ``timeout`` s.
            RuntimeError: A node (other than a killed one) failed.
        """
        deadline = time.monotonic() + timeout
        while self.tick < tick and not self.processes.finished:
            if time.monotonic() > deadline:
                raise TimeoutError(f"tick {tick} not reached in {timeout} s (at {self.tick})")
            self.processes.check()
            time.sleep(0.05)
        return self.tick

    def wait_seconds(self, seconds: float) -> None:
        """Let the trial run ``seconds`` of wall time, checking the nodes."""
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self.processes.check()
            time.sleep(0.05)

    def kill(self, name: str) -> int:
        """SIGKILL node ``name``; returns its exit code (-9)."""
        return self.processes.kill(name)

    def restart(self, name: str, command: list[str] | None = None, **popen) -> None:
        """Start node ``name`` again (its own command line unless ``command``)."""
        self.processes.start(name, command, **popen)

    def set_params(self, node: str, timeout: float = 30.0, **values) -> None:
        """Set parameters of node ``node`` (fully qualified, e.g. ``/sensors``) at runtime.

        Raises:
            RuntimeError: The service is not there, or the node refuses a value.
        """
        from rcl_interfaces.srv import SetParameters
        from rclpy.parameter import Parameter

        client = self.watcher.node.create_client(SetParameters, f"{node}/set_parameters")
        try:
            if not client.wait_for_service(timeout_sec=timeout):
                raise RuntimeError(f"{node}/set_parameters is not available")
            request = SetParameters.Request(
                parameters=[Parameter(k, value=v).to_parameter_msg() for k, v in values.items()]
            )
            # Setting a value is idempotent: ask again every 5 s. A server that has not yet
            # matched this client's reply reader drops its answer ("failed to send response
            # (timeout)", seen in a rehearsal: the camera-5 Hz row waited 120 s for nothing).
            future = client.call_async(request)
            asked = time.monotonic()
            deadline = asked + timeout
            while not future.done() and time.monotonic() < deadline:
                if time.monotonic() - asked > 5.0:
                    future, asked = client.call_async(request), time.monotonic()
                time.sleep(0.02)
            if not future.done():
                raise RuntimeError(f"{node}/set_parameters did not answer")
            refused = [r.reason for r in future.result().results if not r.successful]
            if refused:
                raise RuntimeError(f"{node} refused {values}: {refused}")
        finally:
            self.watcher.node.destroy_client(client)

    def call(self, service: str, timeout: float = 60.0) -> str:
        """Call a ``std_srvs/Trigger`` service (e.g. ``/supervisor/pause``); its message.

        Raises:
            RuntimeError: The service is not there, does not answer, or refuses.
        """
        from std_srvs.srv import Trigger

        client = self.watcher.node.create_client(Trigger, service)
        try:
            if not client.wait_for_service(timeout_sec=timeout):
                raise RuntimeError(f"{service} is not available")
            future = client.call_async(Trigger.Request())
            deadline = time.monotonic() + timeout
            while not future.done() and time.monotonic() < deadline:
                time.sleep(0.02)
            if not future.done():
                raise RuntimeError(f"{service} did not answer")
            if not future.result().success:
                raise RuntimeError(f"{service} refused: {future.result().message}")
            return future.result().message
        finally:
            self.watcher.node.destroy_client(client)

    def wait_for(self, condition, timeout: float = 240.0, what: str = "condition") -> None:
        """Wait until ``condition()`` holds, checking the nodes.

        Raises:
            TimeoutError: Not within ``timeout`` s.
        """
        deadline = time.monotonic() + timeout
        while not condition():
            if time.monotonic() > deadline:
                raise TimeoutError(f"{what}: not within {timeout} s (at tick {self.tick})")
            self.processes.check()
            time.sleep(0.05)

    def statuses(self, name: str, since_tick: int = -1) -> list[Status]:
        """The ``/diagnostics`` statuses of ``name`` (exact), heard at tick >= ``since_tick``."""
        with self.watcher.lock:
            return [s for s in self.watcher.statuses if s.name == name and s.tick >= since_tick]

    def messages(self, name: str, since_tick: int = -1) -> list[str]:
        """Messages of :meth:`statuses`."""
        return [s.message for s in self.statuses(name, since_tick)]

    def result(self, timeout: float = 600.0) -> dict:
        """Wait for the simulator's last tick; its ``result.json``."""
        return self.processes.wait(timeout)

    def log(self, name: str) -> str:
        """Node ``name``'s log so far."""
        path = self.processes.log(name)
        return path.read_text(errors="replace") if path.exists() else ""

    def close(self) -> None:
        """Stop the nodes (Ctrl-C, the recorder last) and the watcher."""
        try:
            self.processes.stop()
        finally:
            self.watcher.close()

    def __enter__(self) -> FaultTrial:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
