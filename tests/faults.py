"""Fault injection for trials through the nodes (docs/reliability.md, "Fault matrix").

:class:`FaultTrial` runs a lockstep trial with every node its own process
(:class:`excavation_bringup.launch.ProcessLauncher`, what ``ant-trial --processes`` runs) and
a watcher node in this process that listens on the same ROS domain: the tick (``/clock``),
every ``/diagnostics`` status, and with full perception the true and the mapped height
maps. A test kills a node (SIGKILL), restarts it, changes a node's parameters at runtime
(the synthetic sensors' fault knobs) and then reads what the system did from the watcher,
the simulator's result and the bag. A new row of the matrix is a few lines::

    def test_blade_driver_row(tmp_path, domain):
        with FaultTrial(tmp_path, domain, steps=40) as trial:
            trial.wait_tick(5)
            trial.kill("blade_driver_1")
            trial.wait_tick(trial.tick + 3)
            trial.restart("blade_driver_1")
            result = trial.result()
        assert result["missed_blade_setpoints"]["1"] >= 1

The watcher is :class:`helpers.watchers.FaultWatcher`; its statuses are
:class:`helpers.watchers.Status`.
"""

from __future__ import annotations

import os
import time
from pathlib import Path

from helpers.watchers import FaultWatcher, Status

from excavation_bringup.deployment import Deployment
from excavation_bringup.graph import build
from excavation_bringup.launch import ProcessLauncher


class FaultTrial:
    """A process trial with a watcher; a context manager that stops everything at the end.

    Args:
        workdir: Logs, ``result.json``, the calibration (and bags, when asked).
        domain: The trial's ROS domain (a test's ``domain`` fixture).
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
        domain: int,
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
        self.domain = domain
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
        self.watcher = FaultWatcher(self.domain, perception, continuous)
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
