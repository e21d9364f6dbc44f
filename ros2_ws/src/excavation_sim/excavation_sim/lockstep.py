"""The lockstep simulator's tick clock and parameters, as pure Python (no ``rclpy``).

:class:`TickClock` is the state machine of ``ros2 run excavation_sim sim``: it waits until
the whole team is on the graph (for ``startup_period`` seconds without a break), then for
each tick collects one behaviour word per robot (and one blade set-point per robot when
blade drivers are in the loop) until all are in or the tick's timeout has passed, and says
when to apply them. The node only converts messages and calls it; tests drive it with
plain numbers.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field

import numpy as np

from ant_controller.readings import PROFILE_NAMES
from excavation_common.params import param


@dataclass(frozen=True)
class SimParams:
    """Parameters of the lockstep simulator node (``config/sim.yaml``)."""

    blueprint: str = param(
        "default", "blueprint: default, default:D, landing-pad or a file", read_only=True
    )
    profile: str = param(
        "v1",
        "world readings of the paper: v1 or paper (excavation_sim.rules.WORLD_PROFILES)",
        choices=PROFILE_NAMES,
        read_only=True,
    )
    robots: int = param(4, "team size", low=1, high=64)
    steps: int = param(300, "ticks to simulate", low=1, high=10_000_000)
    seed: int = param(0, "scenario seed (as ant-eval --seed)", low=0, high=2**63 - 1)
    scenario: int = param(0, "scenario index within the seed", low=0, high=1_000_000)
    dt: float = param(1.0, "sim time per tick, s", low=1e-3, high=3600.0)
    command_timeout: float = param(1.0, "s to wait for a robot's word", low=1e-3, high=3600.0)
    first_command_timeout: float = param(
        30.0, "s tick 0 waits (controllers compile their kernels)", low=1e-3, high=3600.0
    )
    startup_period: float = param(
        0.5, "s the team must be on the graph before tick 0", low=0.0, high=600.0
    )
    diagnostics_period: float = param(1.0, "s between status reports", low=0.01, high=3600.0)
    blade_driver: bool = param(False, "blades follow blade_driver set-points")
    truth_prefix: str = param("", "prefix of the true poses and heights (perception: full)")
    result_file: str = param("", "JSON file written at the end (empty: none)")
    supervised: bool = param(
        True, "apply ticks only while the team supervisor's heartbeat says armed"
    )
    wait_for_ready: bool = param(
        False, "tick 0 also waits for every controller's latched ready (every trial graph)"
    )
    wait_for_recorder: bool = param(
        False, "tick 0 also waits for the bag recorder (node bag_recorder) to subscribe /clock"
    )


class Action(enum.Enum):
    """What the node must do after :meth:`TickClock.poll`."""

    WAIT = "wait"
    PUBLISH_FIRST = "publish_first"
    APPLY = "apply"


@dataclass
class TickInputs:
    """What one tick collected, ready to apply.

    Attributes:
        masks: One behaviour word per robot (0 for a robot that did not answer or is
            absent).
        missing: Robots whose word did not come in time (absent robots are not missing).
        setpoints: Robot -> blade set-point (blade-driver mode): the one sent under an open
            gate, else the held one (home) where only that came.
        missing_setpoints: Robots present whose set-point did not come in time.
    """

    masks: np.ndarray
    missing: list[int]
    setpoints: dict[int, float]
    missing_setpoints: list[int]


@dataclass
class TickClock:
    """Lockstep tick barrier: publish, collect every robot's word, apply, repeat.

    Times are seconds on the node's clock. Call :meth:`poll` often; it answers
    :attr:`Action.PUBLISH_FIRST` once (publish tick 0), then :attr:`Action.APPLY` whenever
    the current tick's inputs are complete or timed out (call :meth:`take` to get them,
    apply them, then :meth:`published` after publishing the next tick).

    Attributes:
        robots: Team size.
        steps: Ticks to run.
        timeout: Seconds a tick waits for words.
        first_timeout: Seconds tick 0 waits.
        startup_period: Seconds the team must be present before tick 0.
        blade_driver: Also wait for one blade set-point per robot.
        tick: Current tick.
        finished: ``steps`` ticks are done.
        held: True while someone holds the clock (a paused team): no tick is applied.
        absent: Robots not waited for (disabled by the supervisor): they idle.
    """

    robots: int
    steps: int
    timeout: float
    first_timeout: float
    startup_period: float
    blade_driver: bool = False
    tick: int = 0
    finished: bool = False
    held: bool = False
    commands: dict[int, int] = field(default_factory=dict)
    setpoints: dict[int, float] = field(default_factory=dict)
    held_setpoints: dict[int, float] = field(default_factory=dict)
    absent: set[int] = field(default_factory=set)
    ready_since: float | None = None
    wait_started: float | None = None

    @classmethod
    def from_params(cls, p: SimParams) -> TickClock:
        """The clock a node with parameters ``p`` runs."""
        return cls(
            p.robots,
            p.steps,
            p.command_timeout,
            p.first_command_timeout,
            p.startup_period,
            p.blade_driver,
        )

    @property
    def started(self) -> bool:
        """Tick 0 has been published."""
        return self.wait_started is not None

    def on_command(self, robot: int, mask: int) -> None:
        """A robot's word for the current tick (the first one counts; 12 bits kept)."""
        if self.started and not self.finished and 0 <= robot < self.robots:
            self.commands.setdefault(robot, int(mask) & 0xFFF)

    def on_setpoint(self, robot: int, value: float, held: bool = False) -> None:
        """A blade driver's set-point for the current tick.

        The first one sent under an open gate counts. One sent under a closed gate
        (``held``: blade home on e-stop, pause, disable, lost heartbeat) withdraws it until
        the driver sends the tick's own set-point again; only if none comes does the held
        one apply when the tick times out.
        """
        if not (self.started and not self.finished and 0 <= robot < self.robots):
            return
        if held:
            self.held_setpoints[robot] = float(value)
            self.setpoints.pop(robot, None)
        else:
            self.held_setpoints.pop(robot, None)
            self.setpoints.setdefault(robot, float(value))

    def present(self) -> list[int]:
        """Robots waited for this tick (not absent)."""
        return [k for k in range(self.robots) if k not in self.absent]

    def complete(self) -> bool:
        """Every present robot's word (and set-point) of the current tick is in."""
        present = self.present()
        if any(k not in self.commands for k in present):
            return False
        return not self.blade_driver or all(k in self.setpoints for k in present)

    def poll(self, now: float, team_present: bool) -> Action:
        """What to do at ``now``; ``team_present``: every robot's nodes are connected."""
        if self.finished:
            return Action.WAIT
        if not self.started:
            if not team_present:
                self.ready_since = None
                return Action.WAIT
            if self.ready_since is None:
                self.ready_since = now
            if now - self.ready_since >= self.startup_period:
                return Action.PUBLISH_FIRST
            return Action.WAIT
        if self.held:
            return Action.WAIT
        timeout = max(self.first_timeout if self.tick == 0 else self.timeout, self.timeout)
        if not self.complete() and now - self.wait_started < timeout:
            return Action.WAIT
        return Action.APPLY

    def take(self) -> TickInputs:
        """The current tick's inputs (missing words are 0); advances to the next tick."""
        present = self.present()
        masks = np.array(
            [self.commands.get(k, 0) if k in present else 0 for k in range(self.robots)],
            dtype=np.int64,
        )
        missing = [k for k in present if k not in self.commands]
        setpoints = self.held_setpoints | self.setpoints
        missing_sp = [k for k in present if k not in setpoints] if self.blade_driver else []
        out = TickInputs(masks, missing, setpoints, missing_sp)
        self.commands.clear()
        self.setpoints.clear()
        self.held_setpoints.clear()
        self.tick += 1
        if self.tick >= self.steps:
            self.finished = True
        return out

    def published(self, now: float) -> None:
        """The state of the current tick went out at ``now``: its wait starts."""
        self.wait_started = now

    def hold(self, held: bool, now: float) -> None:
        """Hold (pause) or release the clock; a release restarts the tick's wait at ``now``.

        The world does not change while held, so the words already in for the current tick
        stay valid and are kept: a paused trial ends as an unpaused one does.
        """
        if self.held and not held and self.started:
            self.wait_started = now
        self.held = held
