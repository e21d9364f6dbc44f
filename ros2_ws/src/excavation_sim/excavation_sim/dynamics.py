"""Continuous-motion robots on the grid world (docs/field.md).

The lockstep simulator applies a behaviour word to the grid at once; here robots drive.
Each robot is a differential-drive body that integrates its ``cmd_vel`` (forward speed,
yaw rate) every ``dt`` seconds with wheel-speed limits, slip and noise. The soil and the
grid poses stay the world model's (:mod:`excavation_sim.world`): the continuous motion only
decides *when* a grid event happens, and the event itself is the world model's own
``apply_behaviours`` with a one-behaviour word, so the blade equations, push capacity,
climb limits, grid edges and the 2 x 2 footprints (no overlaps) are exactly the lockstep
simulator's:

* **Move.** When a robot driving forward (commanded speed > 0) has moved
  ``commit_fraction`` of a cell ahead of the centre of its grid footprint, its Move
  Forward is applied to the world (throttle from ``drive/throttle``). Accepted: the
  footprint is the next cell and the blade has cut, pushed or filled. Refused (the world
  would set U1: blocked, off the grid, soil beyond the push capacity, a step too high):
  the robot *stalls*, held at that point until it backs off. Move Backward likewise.
* **Turn.** When the yaw has turned more than 45 degrees from the footprint's heading, a
  Turn Right or Turn Left is applied (turns never fail). Random turns are never drawn here:
  the executor is told the direction (the team tick draws it from the world's stream).
* **Blade.** A blade set-point replaces the blade setting; the node applies one when the
  robot's motion of that tick has ended (Table 2 order: blade behaviours after moves).

State: the :class:`~excavation_sim.world.World` (heights, grid robots) plus ``bodies``
``float [n, 3]`` (x, y, yaw in ``map``), commands ``float [n, 2]``, throttle and stall
flags. All randomness comes from one seeded generator.

**Physical soil** (``soil: physical``, :mod:`excavation_sim.soil`): the soil is a fine
height field instead. A robot's blade cuts and pushes it as the robot moves, the pile it
gathers resists the push (McKyes's equation plus the grade), and a robot whose wheels
cannot give that force slips in place (``slipping``). The grid events keep the footprints,
headings and U1 of the world model (other robots, the grid's edge) but move no soil and
check no push capacity or climb: the force does that. After every step the world's
``heights`` are the cells' sub-cell means rounded to whole units (what the controllers
sense); :meth:`Dynamics.fitness` reads the means themselves.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ant_controller.layout import (
    BLADE_HOME,
    MOVE_BACKWARD,
    MOVE_FORWARD,
    THROTTLE_UP,
    TURN_LEFT,
    TURN_RIGHT,
)
from ant_controller.sensing import (
    FORWARD,
    MAX_LOAD,
    blade_offset,
    blade_volume,
    is_tilted_down,
)
from excavation_common.frames import heading_to_yaw, robot_center
from excavation_common.params import param
from excavation_sim.rules import P_NORMAL_CLIMB, P_NORMAL_LOAD, P_THROTTLE_CLIMB, P_THROTTLE_LOAD
from excavation_sim.soil import Site, Soil, SoilParams
from excavation_sim.world import (
    BLADE,
    COL,
    HEADING,
    ROW,
    STUCK,
    World,
    apply_behaviours,
    fitness,
)


@dataclass(frozen=True)
class DynamicsParams:
    """Physical parameters of the continuous-motion robots (the node's parameters).

    Slip and noise default to the documented values (docs/field.md); the parity trial
    sets them to 0.
    """

    dt: float = param(0.05, "integration step, s of sim time", low=0.001, high=1.0)
    track_width: float = param(0.2, "distance between the wheel tracks, m", low=0.01, high=5.0)
    max_wheel_speed: float = param(0.3, "wheel speed limit, m/s", low=0.001, high=10.0)
    slip: float = param(0.03, "fraction of the wheel speed lost to slip", low=0.0, high=0.9)
    turn_slip: float = param(0.05, "fraction of the yaw rate lost to skid", low=0.0, high=0.9)
    speed_noise: float = param(0.005, "std of the forward-speed noise, m/s", low=0.0, high=1.0)
    turn_noise: float = param(0.02, "std of the yaw-rate noise, rad/s", low=0.0, high=10.0)
    pose_noise: float = param(0.002, "std of the published position noise, m", low=0.0, high=1.0)
    yaw_noise: float = param(0.004, "std of the published yaw noise, rad", low=0.0, high=1.0)
    commit_fraction: float = param(
        0.25, "travel (cells) past the footprint centre that commits a move", low=0.05, high=0.45
    )

    @classmethod
    def exact(cls, **changes) -> DynamicsParams:
        """No slip and no noise (the parity setting)."""
        base = dict(slip=0.0, turn_slip=0.0, speed_noise=0.0, turn_noise=0.0)
        base.update(pose_noise=0.0, yaw_noise=0.0)
        base.update(changes)
        return cls(**base)


@dataclass
class Counters:
    """Grid events so far."""

    moves: int = 0
    refused: int = 0
    turns: int = 0
    blade_changes: int = 0
    slips: int = 0  # robot-steps whose push the wheels could not give (soil: physical)


@dataclass(frozen=True)
class WorldResult:
    """A continuous-motion world at the end of a trial (``dynamics``' ``world.json``).

    Attributes:
        fitness: The paper's fitness now.
        heights: The cells' heights, whole units.
        snapshots: The fitness of every snapshot, by its label (``"tick 3"``).
        sim_seconds: Simulated time.
        steps: Simulator steps taken.
        late_steps: Steps a robot's command came late.
        mean_heights: Physical soil: the cells' sub-cell means, units (else ``None``).
        volume: Physical soil: the fine field's total, quanta (else ``None``).
        slips: Physical soil: robot-steps too heavy to push.
    """

    fitness: float
    heights: list[list[int]]
    snapshots: dict[str, float]
    sim_seconds: float
    steps: int
    late_steps: int
    mean_heights: list[list[float]] | None = None
    volume: int | None = None
    slips: int = 0

    def to_json(self) -> dict:
        """JSON-ready values (the soil's fields only with physical soil)."""
        out = {
            "fitness": self.fitness,
            "heights": self.heights,
            "snapshots": self.snapshots,
            "sim_seconds": self.sim_seconds,
            "steps": self.steps,
            "late_steps": self.late_steps,
        }
        if self.volume is not None:
            out |= {"mean_heights": self.mean_heights, "volume": self.volume, "slips": self.slips}
        return out

    @classmethod
    def from_json(cls, data: dict, where: str = "world.json") -> WorldResult:
        """The result :meth:`to_json` wrote.

        Raises:
            ValueError: Naming ``where`` and the field that is missing or malformed.
        """
        try:
            volume = data.get("volume")
            return cls(
                fitness=float(data["fitness"]),
                heights=[[int(h) for h in row] for row in data["heights"]],
                snapshots={str(k): float(v) for k, v in data["snapshots"].items()},
                sim_seconds=float(data["sim_seconds"]),
                steps=int(data["steps"]),
                late_steps=int(data["late_steps"]),
                mean_heights=data.get("mean_heights"),
                volume=None if volume is None else int(volume),
                slips=int(data.get("slips", 0)),
            )
        except KeyError as exc:
            raise ValueError(f"{where}: no field {exc.args[0]!r} in the world's result") from None
        except (TypeError, ValueError, AttributeError) as exc:
            raise ValueError(f"{where}: a malformed world result ({exc})") from None


class Dynamics:
    """Continuous diff-drive robots over a :class:`World` (pure, no ``rclpy``).

    Args:
        world: The grid world (scenario start); its robots become bodies at their cell
            centres and headings.
        params: Physical parameters.
        cell_size: Grid cell size, m.
        rng: Source of slip and noise.
        soil: The soil model; ``None`` or ``soil: grid``: the world model's rules.
        height_unit: Metres per soil unit (the physical soil's scale).
    """

    def __init__(
        self,
        world: World,
        params: DynamicsParams,
        cell_size: float,
        rng: np.random.Generator,
        soil: SoilParams | None = None,
        height_unit: float = 0.05,
    ) -> None:
        self.world = world
        self.params = params
        self.cell = float(cell_size)
        self.rng = rng
        self.soil: Soil | None = None
        if soil is not None and soil.physical:
            soil = soil.resolved()
            rows, cols = world.heights.shape
            capacities = (int(world.params[P_NORMAL_LOAD]), int(world.params[P_THROTTLE_LOAD]))
            site = Site(rows, cols, self.cell, height_unit)
            self.soil = Soil(world.heights, site, soil, capacities=capacities)
            self.soil.settle(self._bodies_at_start(), world.active)
            self.soil.cell_heights(world.heights)
            # A grid event moves the footprint only: no climb limit and no push capacity
            # (the soil and the force decide those), on a copy of the heights.
            self.footprint_params = world.params.copy()
            for key in (P_NORMAL_CLIMB, P_THROTTLE_CLIMB, P_NORMAL_LOAD, P_THROTTLE_LOAD):
                self.footprint_params[key] = 1 << 40
        n = world.n_robots
        self.bodies = np.zeros((n, 3))
        for k in range(n):
            r = world.robots[k]
            x, y = robot_center(int(r[ROW]), int(r[COL]), self.cell)
            self.bodies[k] = (x, y, heading_to_yaw(int(r[HEADING])))
        self.commands = np.zeros((n, 2))
        self.throttle = np.zeros(n, dtype=bool)
        self.stalled = np.zeros(n, dtype=np.int64)  # +1 forward refused, -1 backward refused
        self.slipping = np.zeros(n, dtype=bool)  # the last step's push was too heavy
        self.ground = np.zeros(n, dtype=np.int64)  # physical soil: each blade's reference
        self.lift = np.zeros(n, dtype=np.int64)  # the edge above the ground, quanta
        self.slipped = np.zeros(n)  # slipped distance the wheels have not yet dug, m
        for k in range(n):
            self._measure_ground(k)
        self.time = 0.0
        self.counters = Counters()

    @property
    def n_robots(self) -> int:
        """Number of robots."""
        return self.world.n_robots

    def _bodies_at_start(self) -> np.ndarray:
        out = np.zeros((self.world.n_robots, 3))
        for k, r in enumerate(self.world.robots):
            x, y = robot_center(int(r[ROW]), int(r[COL]), self.cell)
            out[k] = (x, y, heading_to_yaw(int(r[HEADING])))
        return out

    # --- inputs -----------------------------------------------------------------------------

    def command(self, k: int, linear: float, angular: float) -> None:
        """Robot k's ``cmd_vel`` (non-finite values count as zero)."""
        self.commands[k] = (
            linear if math.isfinite(linear) else 0.0,
            angular if math.isfinite(angular) else 0.0,
        )

    def set_blade(self, k: int, blade: int) -> None:
        """Robot k's blade setting (a code of ``excavation_common.constants``).

        Physical soil: the servo sets the edge against the front axle's ground now.
        """
        if int(self.world.robots[k, BLADE]) != blade:
            self.counters.blade_changes += 1
        self.world.robots[k, BLADE] = blade
        self._measure_ground(k)

    def _measure_ground(self, k: int) -> None:
        """Physical soil: robot k's blade edge, set against the ground under its front axle.

        The edge stands ``b_h`` units off that ground; with ``epsilon`` a blade set above
        that holds nothing (no soil above that edge ahead of it) cuts as level, the
        paper's epsilon rule taken, like the grid's, once per move.
        """
        soil = self.soil
        if soil is None:
            return
        x, y, yaw = self.bodies[k]
        self.ground[k] = soil.ground(x, y, yaw)
        offset = blade_offset(int(self.world.robots[k, BLADE]))
        self.lift[k] = offset * soil.q
        if soil.params.epsilon and offset > 0 and soil.held(x, y, yaw, self.edge(k)) == 0:
            self.lift[k] = 0

    def edge(self, k: int) -> int:
        """Physical soil: robot k's blade edge height, quanta (see ``_measure_ground``)."""
        return int(self.ground[k] + self.lift[k])

    # --- stepping ---------------------------------------------------------------------------

    def wheel_speeds(self, linear: float, angular: float) -> tuple[float, float]:
        """``(v, w)`` after the wheel-speed limit (each track clipped, the ratio kept)."""
        half = self.params.track_width / 2
        left, right = linear - angular * half, linear + angular * half
        top = max(abs(left), abs(right))
        if top > self.params.max_wheel_speed:
            scale = self.params.max_wheel_speed / top
            left, right = left * scale, right * scale
        return (left + right) / 2, (right - left) / self.params.track_width

    def step(self) -> None:
        """Advance every robot by ``dt``, robot 0 first, applying the grid events."""
        p = self.params
        for k in range(self.n_robots):
            if not self.world.active[k]:
                continue
            v, w = self.wheel_speeds(*self.commands[k])
            v *= 1.0 - p.slip
            w *= 1.0 - p.turn_slip
            if p.speed_noise and v:
                v += self.rng.normal(0.0, p.speed_noise)
            if p.turn_noise and (v or w):
                w += self.rng.normal(0.0, p.turn_noise)
            x, y, yaw = self.bodies[k]
            if self.soil is not None:
                v = self._push(k, v)
            if abs(w) < 1e-9:
                x += v * math.cos(yaw) * p.dt
                y += v * math.sin(yaw) * p.dt
            else:
                x += v / w * (math.sin(yaw + w * p.dt) - math.sin(yaw))
                y -= v / w * (math.cos(yaw + w * p.dt) - math.cos(yaw))
            yaw = math.atan2(math.sin(yaw + w * p.dt), math.cos(yaw + w * p.dt))
            self.bodies[k] = (x, y, yaw)
            if self.soil is not None and v > 0 and self.world.robots[k, BLADE] != BLADE_HOME:
                self.soil.cut(x, y, yaw, self.edge(k))
            self._events(k)
        if self.soil is not None:
            self.soil.settle(
                self.bodies, self.world.active, self.world.robots[:, BLADE] != BLADE_HOME
            )
            self.soil.cell_heights(self.world.heights)
        self.time += p.dt

    def _push(self, k: int, v: float) -> float:
        """Robot k's forward speed after the soil: 0 when its wheels cannot give the push.

        With terramechanics traction the wheels slip in proportion to the load, so a heavy
        push also slows the robot (:meth:`~excavation_sim.soil.Physics.speed_factor`).
        """
        self.slipping[k] = False
        if v <= 0:
            return v
        soil = self.soil
        x, y, yaw = self.bodies[k]
        blade = 0.0
        physics = soil.physics
        if self.world.robots[k, BLADE] != BLADE_HOME:
            blade = soil.resistance(x, y, yaw, self.edge(k))
            if soil.params.force_control and physics.blade_limit and blade > physics.blade_limit:
                # the blade's force control lifts the edge until the force is in its limit
                self.lift[k] += soil.relief(x, y, yaw, self.edge(k), physics.blade_limit)
                blade = soil.resistance(x, y, yaw, self.edge(k))
        grade = physics.mass * physics.gravity * math.sin(soil.pitch(x, y, yaw))
        factor = physics.speed_factor(blade + grade, blade, bool(self.throttle[k]))
        if factor == 0.0:
            # the wheels spin in place: what they slip carries soil back from under them
            self.slipped[k] = soil.dig_in(x, y, yaw, self.slipped[k] + v * self.params.dt)
            self.slipping[k] = True
            self.counters.slips += 1
            return 0.0
        return v * factor

    def offset(self, k: int) -> float:
        """Robot k's travel past its footprint centre along its grid heading, in cells."""
        r = self.world.robots[k]
        cx, cy = robot_center(int(r[ROW]), int(r[COL]), self.cell)
        yaw = heading_to_yaw(int(r[HEADING]))
        x, y, _ = self.bodies[k]
        return ((x - cx) * math.cos(yaw) + (y - cy) * math.sin(yaw)) / self.cell

    def _apply(self, k: int, bit: int) -> bool:
        """One behaviour of robot k through the world model; True when not refused."""
        word = 1 << bit
        if self.throttle[k]:
            word |= 1 << THROTTLE_UP
        w = self.world
        if self.soil is None:
            apply_behaviours(w.heights, w.robots, w.active, k, word, w.rng, w.params)
            return not w.robots[k, STUCK]
        # Physical soil: the footprint moves with no climb limit or push capacity (the
        # soil and the force decide those), on a copy of the heights (the fine field is the
        # soil). With ``refusals`` an engaged blade keeps the grid's refusals (a push into
        # another robot or off the site); without, the move is made as with the blade home.
        blade = w.robots[k, BLADE]
        if not self.soil.params.refusals:
            w.robots[k, BLADE] = BLADE_HOME
        heights = w.heights.copy()
        apply_behaviours(heights, w.robots, w.active, k, word, w.rng, self.footprint_params)
        w.robots[k, BLADE] = blade
        return not w.robots[k, STUCK]

    def _events(self, k: int) -> None:
        commit = self.params.commit_fraction
        robots = self.world.robots
        # Turns: the footprint's heading follows the yaw past 45 degrees.
        while True:
            error = math.remainder(
                self.bodies[k, 2] - heading_to_yaw(int(robots[k, HEADING])), 2 * math.pi
            )
            if error < -math.pi / 4:
                self._apply(k, TURN_RIGHT)
            elif error > math.pi / 4:
                self._apply(k, TURN_LEFT)
            else:
                break
            self.counters.turns += 1
            self.stalled[k] = 0
        d = self.offset(k)
        linear = self.commands[k, 0]
        for sign, bit in ((1, MOVE_FORWARD), (-1, MOVE_BACKWARD)):
            if sign * linear > 0 and sign * d > commit and self.stalled[k] != sign:
                if self._apply(k, bit):
                    self.counters.moves += 1
                    self._measure_ground(k)
                    d = self.offset(k)
                else:
                    self.counters.refused += 1
                    self.stalled[k] = sign
            if self.stalled[k] == sign and sign * d > commit:
                self._hold(k, sign * commit - d)
                d = sign * commit
        if abs(d) < commit / 2:
            self.stalled[k] = 0

    def _hold(self, k: int, cells: float) -> None:
        """Move robot k by ``cells`` along its grid heading (a stalled robot stays put)."""
        h = int(self.world.robots[k, HEADING])
        self.bodies[k, 0] += cells * self.cell * FORWARD[h, 1]
        self.bodies[k, 1] += cells * self.cell * FORWARD[h, 0]

    def warm(self) -> None:
        """Compile the world-model kernels a grid event runs, on copies of the world.

        Called before the first step: otherwise the first committed move compiles them
        while the robots drive (on a cold numba cache, 20 s in which a wall-clock world
        stands still and every executor sees no progress). Changes nothing.
        """
        w = self.world
        for bit in (MOVE_FORWARD, TURN_RIGHT):
            robots = w.robots.copy()
            apply_behaviours(
                w.heights.copy(), robots, w.active.copy(), 0, 1 << bit, w.rng.copy(), w.params
            )
        self.blade_force(0, 1.0)
        self.tilted(0)
        if self.soil is not None:
            soil = self.soil
            fine, loose = soil.fine.copy(), soil.loose.copy()
            x, y, yaw = self.bodies[0]
            soil.cut(x, y, yaw, self.edge(0))
            soil.settle(self.bodies, w.active)
            soil.fine[...] = fine
            soil.loose[...] = loose
            self.fitness()

    # --- outputs ----------------------------------------------------------------------------

    def measured(self, k: int) -> tuple[float, float, float]:
        """Robot k's pose as a localiser would report it (with ``pose_noise``)."""
        x, y, yaw = self.bodies[k]
        p = self.params
        if p.pose_noise:
            x += self.rng.normal(0.0, p.pose_noise)
            y += self.rng.normal(0.0, p.pose_noise)
        if p.yaw_noise:
            yaw += self.rng.normal(0.0, p.yaw_noise)
        return float(x), float(y), float(yaw)

    def fitness(self) -> float:
        """The paper's fitness; with physical soil, of the cells' sub-cell means.

        (``fitness_heights: rounded``: of the whole-unit heights the controllers read.)
        """
        if self.soil is None or self.soil.params.fitness_heights == "rounded":
            return self.world.fitness()
        w = self.world
        return float(fitness(self.soil.cell_means(), w.zones, w.goal))

    def blade_force(self, k: int, max_force: float) -> float:
        """Push force on robot k's blade (N): the held soil, ``max_force`` at 24 units.

        Physical soil: McKyes's force on the blade, scaled so that the level push the
        throttle-up motor just gives (24-25 units) reads ``max_force``; with ``load:
        volume``, the grid's rule on the whole-unit heights.
        """
        if self.soil is not None and self.soil.params.load == "force":
            blade = int(self.world.robots[k, BLADE])
            if blade == BLADE_HOME:
                return 0.0
            x, y, yaw = self.bodies[k]
            force = self.soil.resistance(x, y, yaw, self.edge(k))
            return force * max_force / self.soil.physics.load_scale()
        r = self.world.robots[k]
        volume = blade_volume(
            self.world.heights, int(r[ROW]), int(r[COL]), int(r[HEADING]), int(r[BLADE])
        )
        return float(volume) * max_force / MAX_LOAD

    def tilted(self, k: int) -> bool:
        """R1: robot k stands tilted nose down (the world model's rule)."""
        r = self.world.robots[k]
        return bool(is_tilted_down(self.world.heights, int(r[ROW]), int(r[COL]), int(r[HEADING])))
