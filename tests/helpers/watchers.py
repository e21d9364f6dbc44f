"""Watchers of a running trial: the test's own node on the trial's ROS domain.

* :class:`DomainWatcher`: what every watcher is, an rclpy context of its own on a domain,
  a node and a single-threaded executor;
* :class:`OperatorWatcher`: the operator's side of a lockstep trial, spun in the test's
  thread (``spin_until``): the tick, ``/sim``'s statuses, the blade drivers' set-points and
  the enables; calls the supervisor's services and runs ``ant-operator``;
* :class:`FaultWatcher`: the fault matrix's watcher, spun in a background thread: the tick
  (``/clock`` or the team tick's), every ``/diagnostics`` status, the height maps;
* :func:`occlude`: the occlusion sequence, hiding LEDs from the synthetic camera through
  ``/sensors``' ``occlude`` parameter.

:class:`OperatorWatcher` and :func:`occlude` serve the oversight tests
(``tests/test_trial_oversight.py``, ``tests/test_continuous_oversight.py``, whose continuous
watcher extends :class:`OperatorWatcher`) and ``tests/test_peer_kills.py``;
:class:`FaultWatcher` and :class:`Status` are ``tests/faults.py``'s.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field

import numpy as np
import pytest

from helpers.operator import operator
from helpers.trials import ROBOTS


class DomainWatcher:
    """An rclpy context of its own on ROS domain ``domain``, a node ``name`` in it and a
    single-threaded executor spinning that node.

    Args:
        domain: The trial's ROS domain.
        name: The node's name.
        signal_handlers: Let rclpy install its signal handlers (Ctrl-C shuts the context
            down); off for a watcher spun in a background thread.
    """

    def __init__(self, domain: int, name: str, signal_handlers: bool = True) -> None:
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node
        from rclpy.signals import SignalHandlerOptions

        self.context = Context()
        if signal_handlers:
            rclpy.init(context=self.context, domain_id=domain)
        else:
            rclpy.init(
                context=self.context,
                domain_id=domain,
                signal_handler_options=SignalHandlerOptions.NO,
            )
        self.node = Node(name, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)


class OperatorWatcher(DomainWatcher):
    """The operator's side of a lockstep trial, spun in this thread.

    Attributes:
        tick: The latest ``/clock`` second (-1 before tick 0).
        tick_wall: ``(tick, wall time)`` of every ``/clock``.
        sim_reports: ``(wall, message)`` of ``/sim``'s ``/diagnostics`` statuses.
        servo: Per robot, ``(wall, stamp sec, value, held)`` of its blade set-points.
        enabled: Per robot, its ``enabled`` values in order.
    """

    def __init__(self, domain: int, robots: int = ROBOTS):
        from diagnostic_msgs.msg import DiagnosticArray
        from excavation_interfaces.msg import BladeCommand
        from rosgraph_msgs.msg import Clock
        from std_msgs.msg import Bool

        from excavation_common.ros import LATCHED

        super().__init__(domain, "test_operator")
        self.tick = -1
        self.tick_wall: list[tuple[int, float]] = []
        self.servo = {k: [] for k in range(robots)}  # (wall, stamp sec, value, held)
        self.enabled = {k: [] for k in range(robots)}

        def on_clock(msg):
            self.tick = msg.clock.sec
            self.tick_wall.append((self.tick, time.monotonic()))

        self.node.create_subscription(Clock, "/clock", on_clock, 10)
        self.sim_reports: list[tuple[float, str]] = []  # (wall, message) of /sim's statuses

        def on_diagnostics(msg):
            self.sim_reports += [
                (time.monotonic(), s.message) for s in msg.status if s.name == "/sim"
            ]

        self.node.create_subscription(DiagnosticArray, "/diagnostics", on_diagnostics, 50)
        for k in range(robots):
            self.node.create_subscription(
                BladeCommand,
                f"/robot_{k}/blade/servo_command",
                lambda m, k=k: self.servo[k].append(
                    (time.monotonic(), m.stamp.sec, m.position, m.held)
                ),
                50,
            )
            self.node.create_subscription(
                Bool, f"/robot_{k}/enabled", lambda m, k=k: self.enabled[k].append(m.data), LATCHED
            )

    def spin_until(self, condition, timeout=120.0) -> bool:
        """Spin until ``condition()`` holds or ``timeout`` s pass; whether it holds."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if condition():
                return True
            self.executor.spin_once(timeout_sec=0.02)
        return condition()

    def call(self, name: str, timeout: float = 30.0, tries: int = 1):
        """Call a Trigger service; ``tries`` > 1 re-sends an unanswered (idempotent) request.

        Returns:
            ``(response, wall time the last request was sent)``.
        """
        from std_srvs.srv import Trigger

        client = self.node.create_client(Trigger, name)
        assert client.wait_for_service(timeout_sec=timeout), name
        for _ in range(tries):
            sent = time.monotonic()
            future = client.call_async(Trigger.Request())
            if self.spin_until(future.done, timeout / tries):
                break
        assert future.done(), f"{name}: no answer"
        self.node.destroy_client(client)
        return future.result(), sent

    def operator(self, domain: int, *args: str):
        """``ant-operator ARGS`` as a separate process, spinning meanwhile (no queue overflows)."""
        done = {}
        thread = threading.Thread(
            target=lambda: done.setdefault("r", operator(domain, *args, timeout="30"))
        )  # a loaded machine can take seconds to discover the services
        thread.start()
        assert self.spin_until(lambda: not thread.is_alive(), timeout=120)
        thread.join()
        return done["r"]

    def held_since(self, since: float) -> dict[int, float]:
        """Robot -> wall time of its first held (home) set-point after ``since``."""
        out = {}
        for k, msgs in self.servo.items():
            for wall, _, value, held in msgs:
                if wall >= since and held:
                    assert value == pytest.approx(0.10)
                    out[k] = wall
                    break
        return out

    def resting_home(self, since: float, deadman: float = 0.5) -> dict[int, float]:
        """Robot -> wall time its blade went home, for robots whose last set-point is home
        (held), asked once the deadman has passed since ``since`` (before that they may still
        send open set-points). A driver sends one held set-point per tick, so one sent in
        this tick before ``since`` (a heartbeat gap on a loaded machine) is not sent again."""
        if time.monotonic() - since <= 2 * deadman:
            return {}
        out = {}
        for k, msgs in self.servo.items():
            if not msgs or not msgs[-1][3]:
                continue
            i = len(msgs) - 1
            while i > 0 and msgs[i - 1][3]:
                i -= 1
            assert msgs[-1][2] == pytest.approx(0.10)
            out[k] = msgs[i][0]
        return out

    def close(self):
        """Stop the executor, destroy the node, shut the context down."""
        import rclpy

        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def occlude(watch, leds: str, timeout: float = 30.0) -> None:
    """Hide LEDs from the synthetic camera of a running trial (full perception).

    Sets the ``/sensors`` node's ``occlude`` parameter through its ``set_parameters``
    service and asserts the node took it.

    Args:
        watch: A watcher spun in this thread (``node`` and ``spin_until``), e.g. an
            :class:`OperatorWatcher`.
        leds: The LEDs to hide, ``ROBOT:front|rear`` separated by commas
            (``"2:front,2:rear"`` hides robot 2); ``""`` shows every LED again.
        timeout: Seconds to wait for the service, and again for its answer.
    """
    from rcl_interfaces.msg import Parameter as ParameterMsg
    from rcl_interfaces.msg import ParameterType, ParameterValue
    from rcl_interfaces.srv import SetParameters

    client = watch.node.create_client(SetParameters, "/sensors/set_parameters")
    assert client.wait_for_service(timeout_sec=timeout)
    value = ParameterValue(type=ParameterType.PARAMETER_STRING, string_value=leds)
    future = client.call_async(
        SetParameters.Request(parameters=[ParameterMsg(name="occlude", value=value)])
    )
    assert watch.spin_until(future.done, timeout) and future.result().results[0].successful


@dataclass
class Status:
    """One ``/diagnostics`` status as the :class:`FaultWatcher` heard it."""

    wall: float
    tick: int
    name: str
    level: int
    message: str
    values: dict[str, str] = field(default_factory=dict)


class FaultWatcher(DomainWatcher):
    """The fault matrix's watcher, spun in a background thread (read under ``lock``).

    Args:
        domain: The trial's ROS domain.
        perception: The trial's perception; with ``"full"`` the true and the mapped height
            maps are kept too (``maps["truth"]``, ``maps["mapped"]``, by stamp).
        continuous: The tick is the team tick's (``/team/tick``), not ``/clock``'s.
    """

    def __init__(self, domain: int, perception: str, continuous: bool = False) -> None:
        from diagnostic_msgs.msg import DiagnosticArray
        from excavation_interfaces.msg import Tick
        from rosgraph_msgs.msg import Clock
        from sensor_msgs.msg import Image

        from excavation_common.ros import LATCHED

        super().__init__(domain, "fault_watcher", signal_handlers=False)
        self.lock = threading.Lock()
        self.tick = -1
        self.ticks_seen: list[int] = []
        self.statuses: list[Status] = []
        self.maps: dict[str, dict[tuple[int, int], np.ndarray]] = {"truth": {}, "mapped": {}}
        if continuous:  # the team tick's tick (sim time runs on between ticks)
            self.node.create_subscription(Tick, "/team/tick", self.on_team_tick, 100)
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
        """The continuous trial's tick (``/team/tick``)."""
        with self.lock:
            self.tick = int(msg.tick)
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
