"""The team tick: the field's version of the simulator's lockstep, as a pure state machine.

In the lockstep simulator a behaviour word is applied to the grid at once; in the dome (or
the continuous ``dynamics`` simulator) a robot takes seconds to drive a cell. The team tick
turns that back into ticks the controllers can run on unchanged, in their lockstep mode:

1. **Snapshot.** Tick t starts once a perception snapshot taken after the motion of tick
   t - 1 ended is in: every robot's pose, the height map and every blade state stamped at
   or after the moment the last robot finished (``settle`` later), each blade at the
   setting its word asked for (or ``blade_wait`` has passed). It asks for one on
   ``/team/snapshot`` (the simulator answers; a dome's camera and laser run anyway). With
   ``snapshot_ack`` the simulator acknowledges the request once it has taken the snapshot
   (:meth:`TeamTick.on_ack`), and a request not acknowledged within ``snapshot_retry``
   wall seconds (it was lost: sent before the simulator's subscription was matched, say)
   is sent again, unchanged; the simulator takes a request only once, so a late
   acknowledgement never makes a second frame and sweep. A snapshot taken but still
   incomplete ``snapshot_retry`` after the request (a robot the camera does not see) asks
   for another instant, so that the lost-robot policy sees further frames. The snapshot is
   republished stamped ``t * tick_period`` with every robot's U1 (its executor aborted:
   stuck).
2. **Words.** Every controller answers with one word (the first word after the snapshot
   counts; ``word_timeout`` / ``first_word_timeout`` wall seconds, then a silent robot
   idles with word 0, as in the lockstep simulator).
3. **Motion.** Random turns are drawn for the words that have one, in robot order, from the
   world's own random-turn stream (``excavation_sim.world.next_random`` seeded by the
   scenario), so a random turn turns the same way as in ``ant-eval``. Robots then move in
   robot-index order, the world model's rule: robot j waits for every robot i < j whose
   reach (footprint grown by ``reach`` cells: every cell a move and its blade can touch in
   one tick) overlaps its own; robots with disjoint reaches move at once, which cannot
   change the result because their moves touch disjoint cells. A robot without a motion
   behaviour waits for nobody and blocks nobody. A robot whose executor does not finish
   within ``motion_limit`` seconds is reported and the tick goes on without it (stuck).

Oversight (docs/architecture.md, "Operator oversight and safety"): the tick runs only while
the team is :attr:`TeamTick.armed` (the node sets it from the supervisor's heartbeat, with
the 0.5 s deadman, and the e-stop). Not armed, no snapshot is taken, no word is turned into
goals and no further goal is granted; a pause while robots drive leaves their goals to their
executors (which stop and carry on after the resume), and time not armed does not count
toward ``motion_limit``. A snapshot the team was held for by the operator (a pause, a
disarm or an e-stop: :attr:`TeamTick.hold` says why the team is held) is asked for again
once it is armed, so that it shows the site as it is then: the operator may have moved
something by hand. A hold for want of heartbeats (:data:`GAPS`: a loaded machine's hiccup,
a supervisor not heard yet; the gates closed, nothing was driven and no one was let in)
only delays the tick, however long it lasts: the request stands, and asking again would
render another frame and sweep and move the simulated sensors' noise stream on; only the
blades get ``blade_wait`` again to reach their settings (a blade driver homes its blade
when heartbeats stop). (A supervisor that restarts in the dome starts disarmed, which is
the operator's hold.) Robots in :attr:`TeamTick.absent` (disabled or lost:
``/robot_k/enabled`` false) are not waited for: the snapshot needs no pose of theirs, their
word is 0 and their motion counts as done at once.

Times: ``now`` is the node clock (sim time in CI), ``wall`` a monotonic wall clock for the
controllers' answers. The node turns the returned actions (:data:`TickAction`: one frozen
dataclass per kind) into messages, in the order returned.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum
from typing import Any

import numpy as np

from blade_driver.core import blade_setting
from excavation_common.behaviour import MOTION_BITS, RANDOM_TURN
from excavation_common.params import param
from excavation_sim.world import next_random

RIGHT, LEFT = 1, -1
HEARTBEAT_GAP = "heartbeat lost"
""":attr:`TeamTick.hold` of a team held only because heartbeats stopped coming
(:meth:`excavation_common.safety.MotionGate.kind` of the gate's reason)."""
NO_HEARTBEAT = "no heartbeat yet"
""":attr:`TeamTick.hold` before the supervisor's first heartbeat (nothing has moved yet)."""
GAPS = (HEARTBEAT_GAP, NO_HEARTBEAT)
"""Holds that cannot have changed the site: no new snapshot after them."""
STAMP_SLACK = 1e-6
"""Seconds: stamps are integer nanoseconds, times here floats (0.1 + 3.65 > 3.75)."""


# --- actions: what the tick asks its node to send --------------------------------------------


@dataclass(frozen=True)
class Snapshot:
    """The perception snapshot of one tick: the payloads the node stored, per robot.

    ``poses`` and ``blades`` hold, per robot, the message of its newest pose and blade
    state (``None`` for a robot never seen: an absent one); ``heights`` the newest height
    map; ``stuck`` every robot's U1 (its executor aborted the last goal, or it was left out).
    """

    poses: tuple[Any, ...]
    heights: Any
    blades: tuple[Any, ...]
    stuck: tuple[bool, ...]


@dataclass(frozen=True)
class RequestSnapshot:
    """Ask for a snapshot (``/team/snapshot``) for ``tick``: taken at ``not_before`` (s) or later.

    A request not acknowledged is sent again unchanged.
    """

    tick: int
    not_before: float


@dataclass(frozen=True)
class PublishTick:
    """Republish the snapshot of tick ``tick`` stamped ``stamp`` (s): the controllers decide."""

    tick: int
    stamp: float
    snapshot: Snapshot


@dataclass(frozen=True)
class SendGoal:
    """Robot ``robot`` may move: its ``word`` of tick ``tick`` (stamped ``stamp``, s).

    ``turn`` is the random turn's direction (``RIGHT``, ``LEFT``; 0: the word has none).
    """

    robot: int
    tick: int
    stamp: float
    word: int
    turn: int


@dataclass(frozen=True)
class Report:
    """Something the operator should read (logged, kept for the result, on ``/diagnostics``)."""

    message: str


@dataclass(frozen=True)
class Finished:
    """The last tick's snapshot is in: write the result and stop."""


TickAction = RequestSnapshot | PublishTick | SendGoal | Report | Finished
"""Every action :class:`TeamTick` returns (``typing.get_args`` lists the classes)."""


@dataclass(frozen=True)
class TickSummary:
    """What a team tick's trial did: its result, in memory and as JSON (``result.json``).

    Attributes:
        ticks: Ticks run.
        commands: Every tick's words, robot by robot.
        tick_wall: Wall seconds of every tick (from its snapshot to the next tick's, the
            last to the end of its motion).
        stuck_events: Robot-ticks with U1 set.
        missed: Per robot, ticks it idled for want of a word.
        robots_late: Robot-ticks left out for not finishing.
        holds: Times the team was held (paused, e-stopped, disarmed or its heartbeat lost)
            while the ticks ran.
        operator_ticks: Per robot that spent any, the ticks during which the operator's
            override drove it (its executor's ``drive/operator``).
    """

    ticks: int
    commands: list[list[int]]
    tick_wall: list[float]
    stuck_events: int
    missed: dict[int, int]
    robots_late: int
    holds: int
    operator_ticks: dict[int, list[int]] = field(default_factory=dict)

    def to_json(self) -> dict:
        """JSON-ready values (``missed`` keyed by the robot's index as a string)."""
        return {
            "ticks": self.ticks,
            "commands": self.commands,
            "tick_wall": self.tick_wall,
            "stuck_events": self.stuck_events,
            "missed": {str(k): n for k, n in self.missed.items()},
            "robots_late": self.robots_late,
            "holds": self.holds,
            "operator_ticks": {str(k): t for k, t in self.operator_ticks.items()},
        }

    @classmethod
    def from_json(cls, data: dict, where: str = "result.json") -> TickSummary:
        """The summary :meth:`to_json` wrote (extra keys, such as ``reports``, ignored).

        Raises:
            ValueError: Naming ``where`` and the field that is missing or malformed.
        """
        try:
            return cls(
                ticks=int(data["ticks"]),
                commands=[[int(w) for w in tick] for tick in data["commands"]],
                tick_wall=[float(t) for t in data["tick_wall"]],
                stuck_events=int(data["stuck_events"]),
                missed={int(k): int(n) for k, n in data["missed"].items()},
                robots_late=int(data["robots_late"]),
                holds=int(data["holds"]),
                operator_ticks={  # absent from results written before it was recorded
                    int(k): [int(t) for t in ticks]
                    for k, ticks in data.get("operator_ticks", {}).items()
                },
            )
        except KeyError as exc:
            raise ValueError(
                f"{where}: no field {exc.args[0]!r} in the team tick's summary"
            ) from None
        except (TypeError, ValueError, AttributeError) as exc:
            raise ValueError(f"{where}: a malformed team tick summary ({exc})") from None


@dataclass(frozen=True)
class TeamTickParams:
    """Parameters of the team tick (the node's ROS parameters of the same names)."""

    robots: int = param(4, "number of robots", low=1, high=64)
    steps: int = param(300, "ticks to run (0: run until stopped)", low=0)
    tick_period: float = param(1.0, "stamp spacing of the republished ticks, s", low=0.001)
    settle: float = param(0.1, "snapshot taken at least this long after motion ended, s", low=0.0)
    snapshot_retry: float = param(
        2.0, "wall s before an unacknowledged or incomplete snapshot is asked for again", low=0.01
    )
    snapshot_ack: bool = param(
        True, "requests are acknowledged on /team/snapshot_ack (false: none is; a dome)"
    )
    snapshot_limit: float = param(
        30.0, "wall s after which an incomplete snapshot is taken as it is", low=0.01
    )
    blade_wait: float = param(2.0, "longest wait for blades to reach their setting, s", low=0.0)
    motion_limit: float = param(
        120.0, "a robot not finished this long after its goal is left out, s", low=0.1
    )
    word_timeout: float = param(5.0, "wall s to wait for every controller's word", low=0.01)
    first_word_timeout: float = param(
        60.0, "wall s to wait for the words of tick 0 (controllers compile)", low=0.01
    )
    reach: int = param(2, "cells around a footprint one tick's motion can touch", low=0, high=16)
    seed: int = param(0, "scenario seed: the random-turn stream (as ant-eval --seed)", low=0)
    scenario: int = param(0, "scenario index of the seed", low=0)
    blueprint: str = param("default", "blueprint spec (grid size, for the random-turn stream)")


class Phase(Enum):
    """Where the tick is."""

    WAITING = "waiting for the team"
    SNAPSHOT = "waiting for a snapshot"
    WORDS = "waiting for words"
    MOTION = "robots moving"
    FINISHED = "finished"


@dataclass
class Latest:
    """The newest message of one input: its stamp (s) and what the node stored."""

    stamp: float
    value: object
    payload: object = None


@dataclass
class TickRecord:
    """What one tick did (for the trial's result)."""

    tick: int
    words: list[int]
    turns: list[int]
    stuck: list[bool]
    late: list[int]
    started_wall: float
    motion_wall: float = 0.0
    ended_wall: float = 0.0
    operated: set[int] = field(default_factory=set)
    """Robots the operator's override drove at some time during the tick."""


def reach_box(row: int, col: int, reach: int) -> tuple[int, int, int, int]:
    """``(r0, r1, c0, c1)`` inclusive: the footprint at ``(row, col)`` grown by ``reach``."""
    return row - reach, row + 1 + reach, col - reach, col + 1 + reach


def overlap(a: tuple[int, int, int, int], b: tuple[int, int, int, int]) -> bool:
    """True when two inclusive boxes share a cell."""
    return a[0] <= b[1] and b[0] <= a[1] and a[2] <= b[3] and b[2] <= a[3]


def schedule(poses: list[tuple[int, int, int]], words: list[int], reach: int) -> list[set[int]]:
    """For each robot, the robots it must wait for (lower index, overlapping reach)."""
    moving = [bool(w & MOTION_BITS) for w in words]
    boxes = [reach_box(r, c, reach) for r, c, _ in poses]
    return [
        {i for i in range(j) if moving[i] and moving[j] and overlap(boxes[i], boxes[j])}
        for j in range(len(words))
    ]


def draw_turns(words: list[int], rng: np.ndarray) -> list[int]:
    """Random-turn directions in robot order from the world's stream (advances ``rng``)."""
    turns = []
    for word in words:
        if (word >> RANDOM_TURN) & 1:
            turns.append(RIGHT if next_random(rng) >> np.uint64(63) else LEFT)
        else:
            turns.append(0)
    return turns


@dataclass
class TeamTick:
    """The barrier between perception, controllers and executors (pure, no ``rclpy``).

    Feed it inputs (``on_*``), call :meth:`step` often; it returns actions
    (:data:`TickAction`), in the order the node must send them:
    :class:`RequestSnapshot` (ask for a snapshot; sent again unchanged while not
    acknowledged), :class:`PublishTick` (the snapshot of a tick), :class:`SendGoal` (a robot
    may move), :class:`Report` and :class:`Finished`.

    The node sets :attr:`armed` (the team may move) and :attr:`hold` (while not armed, why:
    :meth:`~excavation_common.safety.MotionGate.kind` of the gate's reason; ``None`` counts
    as a hold that may have changed the site) before every :meth:`step`, and keeps
    :attr:`absent`. Every other field is the tick's own state.
    """

    params: TeamTickParams
    rng: np.ndarray
    """The world's random-turn stream (``next_random`` state), advanced by every random turn."""

    # --- set by the node ---------------------------------------------------------------------
    armed: bool = True
    """The team may move (a fresh armed heartbeat, no e-stop)."""
    hold: str | None = None
    """While not armed, why (:data:`GAPS` only delay the snapshot)."""
    absent: set[int] = field(default_factory=set)
    """Robots disabled or lost: not waited for, word 0."""

    # --- where the tick is (read by the node and the tests) ---------------------------------
    phase: Phase = field(default=Phase.WAITING, init=False)
    """The state machine's phase."""
    tick: int = field(default=0, init=False)
    """The tick being run (the next one once its motion ended)."""
    poses: dict[int, Latest] = field(default_factory=dict, init=False)
    """Per robot: its newest pose (value: grid ``(row, col, heading)``)."""
    heights: Latest | None = field(default=None, init=False)
    """The newest height map."""
    blades: dict[int, Latest] = field(default_factory=dict, init=False)
    """Per robot: its newest measured blade (value: the setting)."""
    words: dict[int, int] = field(default_factory=dict, init=False)
    """This tick's words so far, per robot (the first word after the snapshot)."""
    records: list[TickRecord] = field(default_factory=list, init=False)
    """What every tick so far did."""
    stuck: list[bool] = field(default_factory=list, init=False)
    """Per robot: U1 (its executor aborted its last goal, or it was left out)."""
    late: list[int] = field(default_factory=list, init=False)
    """Per robot: ticks it was left out of for not finishing within ``motion_limit``."""
    missed: list[int] = field(default_factory=list, init=False)
    """Per robot: ticks it idled for want of a word."""
    holds: int = field(default=0, init=False)
    """Times the team was held (armed turned false) while the ticks ran."""
    operator: list[bool] = field(default_factory=list, init=False)
    """Per robot: the operator's override drives it now (its executor's ``drive/operator``)."""

    # --- the snapshot request ---------------------------------------------------------------
    _after: float = field(default=0.0, init=False)
    """Node time the last motion ended (or the team was armed after an operator's hold)."""
    _after_wall: float = field(default=0.0, init=False)
    """Wall time of :attr:`_after` (``snapshot_limit`` counts from it)."""
    _asked: float = field(default=0.0, init=False)
    """Wall time the request was last sent (``snapshot_retry`` counts from it)."""
    _not_before: float = field(default=0.0, init=False)
    """The instant the request standing asks for (node time)."""
    _acked: bool = field(default=False, init=False)
    """The simulator acknowledged the request standing (or none will: ``snapshot_ack`` off)."""
    _rearmed: float = field(default=0.0, init=False)
    """Node time the team was last armed again after a hold (blades get ``blade_wait`` anew)."""
    _final: bool = field(default=False, init=False)
    """The last tick's motion ended: its snapshot finishes the run."""

    # --- holds ------------------------------------------------------------------------------
    _was_armed: bool = field(default=True, init=False)
    """:attr:`armed` at the previous :meth:`step` (counts :attr:`holds`)."""
    _last_now: float | None = field(default=None, init=False)
    """Node time of the previous :meth:`step` (held time is added to the grants)."""
    _held: bool = field(default=False, init=False)
    """The snapshot phase is held (not armed) since :attr:`_held_wall`."""
    _held_wall: float = field(default=0.0, init=False)
    """Wall time the snapshot phase's hold began."""
    _held_kinds: list[str] = field(default_factory=list, init=False)
    """Why the snapshot phase was held, each reason once in order."""

    # --- the tick's snapshot, words and motion ----------------------------------------------
    _wall: float = field(default=0.0, init=False)
    """Wall time the tick's snapshot was published (the word timeouts count from it)."""
    _grid: list[tuple[int, int, int]] = field(default_factory=list, init=False)
    """Per robot: its grid pose in the tick's snapshot (``(0, 0, 0)``: none)."""
    _settings: list[int | None] = field(default_factory=list, init=False)
    """Per robot: its blade setting in the tick's snapshot (``None``: none)."""
    _word_of: list[int] = field(default_factory=list, init=False)
    """Per robot: the word it carries out this tick (0: silent or absent)."""
    _turns: list[int] = field(default_factory=list, init=False)
    """Per robot: this tick's random-turn direction (0: none)."""
    _waits: list[set[int]] = field(default_factory=list, init=False)
    """Per robot: the robots it waits for this tick (:func:`schedule`)."""
    _expected: list[int | None] = field(default_factory=list, init=False)
    """Per robot: the blade setting its last word asked for (``None``: unknown)."""
    _granted: dict[int, float] = field(default_factory=dict, init=False)
    """Robots granted their goal this tick: node time of the grant (moved on while held)."""
    _done: set[int] = field(default_factory=set, init=False)
    """Robots whose motion this tick is over (finished, left out or absent)."""

    def __post_init__(self) -> None:
        n = self.params.robots
        self.stuck = [False] * n
        self.late = [0] * n
        self.missed = [0] * n
        self.operator = [False] * n
        self._expected = [None] * n

    # --- inputs -----------------------------------------------------------------------------

    def on_pose(self, k: int, grid_pose: tuple[int, int, int], stamp: float, payload) -> None:
        """Robot k's pose (grid anchor and heading) at ``stamp``."""
        self.poses[k] = Latest(stamp, grid_pose, payload)

    def on_heights(self, stamp: float, payload) -> None:
        """A height map at ``stamp``."""
        self.heights = Latest(stamp, None, payload)

    def on_blade(self, k: int, setting: int, stamp: float, payload) -> None:
        """Robot k's measured blade setting at ``stamp``."""
        self.blades[k] = Latest(stamp, setting, payload)

    def on_ack(self, tick: int, stamp: float) -> None:
        """The simulator took the snapshot of ``tick`` at ``stamp`` (``/team/snapshot_ack``).

        It acknowledges the request sent last only if it is that request's tick, taken at
        or after its ``not_before`` (an older acknowledgement, latched, is another's).
        """
        if (
            self.phase is Phase.SNAPSHOT
            and tick == self.tick
            and stamp >= self._not_before - STAMP_SLACK
        ):
            self._acked = True

    def on_word(self, k: int, word: int) -> None:
        """Robot k's controller answered (the first word of a tick counts)."""
        if self.phase is Phase.WORDS and k not in self.words:
            self.words[k] = int(word) & 0xFFF

    def on_operator(self, k: int, active: bool) -> None:
        """Robot k's executor says whether the operator's override drives it."""
        self.operator[k] = active
        if active and self.records:
            self.records[-1].operated.add(k)

    def on_status(self, k: int, tick: int, terminal: bool, aborted: bool, now: float) -> None:
        """Robot k's executor reported on its goal of ``tick``."""
        if self.phase is Phase.MOTION and tick == self.tick and terminal and k in self._granted:
            if k not in self._done:
                self._done.add(k)
                self.stuck[k] = aborted

    def executor_restarted(self, k: int, now: float) -> list[TickAction]:
        """Robot k's executor was replaced while its goal ran (a new one is on the graph).

        The new executor never heard the old one's goal, so no status of it will come:
        the robot is done for this tick and stuck (U1), as a goal that ended aborted, and
        the tick does not wait ``motion_limit`` for it.
        """
        if self.phase is not Phase.MOTION or k not in self._granted or k in self._done:
            return []
        self._done.add(k)
        self.stuck[k] = True
        return [
            Report(
                f"tick {self.tick}: robot {k}'s executor restarted while its goal ran; the "
                "goal is lost (stuck) and the tick goes on"
            )
        ]

    def summary(self) -> TickSummary:
        """What the ticks so far did (the trial's result; :class:`TickSummary`)."""
        records = self.records
        return TickSummary(
            ticks=len(records),
            commands=[list(r.words) for r in records],
            tick_wall=[
                (later.started_wall if later else r.ended_wall) - r.started_wall
                for r, later in zip(records, [*records[1:], None], strict=True)
            ],
            stuck_events=sum(sum(r.stuck) for r in records),
            missed=dict(enumerate(self.missed)),
            robots_late=sum(self.late),
            holds=self.holds,
            operator_ticks={
                k: ticks
                for k in range(self.params.robots)
                if (ticks := [r.tick for r in records if k in r.operated])
            },
        )

    def start(self, now: float, wall: float = 0.0) -> list[TickAction]:
        """The team is present: ask for the snapshot of tick 0."""
        self.phase = Phase.SNAPSHOT
        self._after, self._after_wall = now, wall
        return self._request(wall)

    # --- the state machine ----------------------------------------------------------------------

    def step(self, now: float, wall: float) -> list[TickAction]:
        """Advance as far as the inputs allow."""
        last, self._last_now = self._last_now, now
        if self.armed != self._was_armed:
            self._was_armed = self.armed
            self.holds += not self.armed
        if not self.armed and self.phase is Phase.MOTION and last is not None:
            for k in self._granted:  # time not armed does not count toward motion_limit
                self._granted[k] += max(0.0, now - last)
        if self.phase is Phase.SNAPSHOT:
            return self._step_snapshot(now, wall)
        if self.phase is Phase.WORDS:
            return self._step_words(now, wall)
        if self.phase is Phase.MOTION:
            return self._step_motion(now, wall)
        return []

    def _request(self, wall: float, not_before: float | None = None) -> list[TickAction]:
        """Ask for the snapshot (``not_before``: a later instant than the tick's own)."""
        self._asked = wall
        self._not_before = self._after + self.params.settle if not_before is None else not_before
        self._acked = not self.params.snapshot_ack  # none will come: taken as it is sent
        return [RequestSnapshot(self.tick, self._not_before)]

    def _resend(self, wall: float) -> list[TickAction]:
        """The request not acknowledged, unchanged (the simulator takes it once)."""
        self._asked = wall
        return [RequestSnapshot(self.tick, self._not_before)]

    def snapshot_ready(self, now: float) -> str | None:
        """What the snapshot still lacks (``None``: complete)."""
        after = self._after + self.params.settle - STAMP_SLACK
        n = self.params.robots
        present = [k for k in range(n) if k not in self.absent]
        for k in present:
            if k not in self.poses or self.poses[k].stamp < after:
                return f"pose of robot {k}"
            if k not in self.blades or self.blades[k].stamp < after:
                return f"blade of robot {k}"
        if self.heights is None or self.heights.stamp < after:
            return "height map"
        if now - max(self._after, self._rearmed) < self.params.blade_wait:
            for k in present:
                if self._expected[k] is not None and self.blades[k].value != self._expected[k]:
                    return f"blade of robot {k} at its setting"
        return None

    def _step_snapshot(self, now: float, wall: float) -> list[TickAction]:
        if not self.armed:
            if not self._held:
                self._held, self._held_wall, self._held_kinds = True, wall, []
            kind = self.hold or "not armed"
            if kind not in self._held_kinds:
                self._held_kinds.append(kind)
            return []
        if self._held:
            self._held = False
            # A blade driver homes its blade when heartbeats stop (its deadman): the blades
            # get blade_wait again to reach their settings.
            self._rearmed = now
            if any(kind not in GAPS for kind in self._held_kinds):
                # the operator held the team: a snapshot of the site as it stands now
                held = wall - self._held_wall
                self._after, self._after_wall = now, wall
                why = ", ".join(self._held_kinds)
                return [
                    Report(f"tick {self.tick}: team held {held:.1f} s ({why}); new snapshot"),
                    *self._request(wall),
                ]
        missing = self.snapshot_ready(now)
        out: list[TickAction] = []
        if missing is not None:
            late = wall - self._after_wall > self.params.snapshot_limit
            if late and self._has_everything():
                out.append(Report(f"tick {self.tick}: snapshot without a fresh {missing}"))
            else:
                if wall - self._asked >= self.params.snapshot_retry:
                    if not self._acked:
                        out.append(
                            Report(f"tick {self.tick}: request not acknowledged; asking again")
                        )
                        out += self._resend(wall)
                    else:  # taken, and still without it: another instant
                        out.append(Report(f"tick {self.tick}: no {missing} yet; asking again"))
                        out += self._request(wall, max(now, self._not_before))
                return out
        if self._final:
            self.phase = Phase.FINISHED
            return out + [Finished()]
        n = self.params.robots
        snapshot = Snapshot(
            poses=tuple(self.poses[k].payload if k in self.poses else None for k in range(n)),
            heights=self.heights.payload,
            blades=tuple(self.blades[k].payload if k in self.blades else None for k in range(n)),
            stuck=tuple(self.stuck),
        )
        self._grid = [self.poses[k].value if k in self.poses else (0, 0, 0) for k in range(n)]
        self._settings = [self.blades[k].value if k in self.blades else None for k in range(n)]
        self.phase = Phase.WORDS
        self.words = {}
        self._wall = wall
        operated = {k for k, on in enumerate(self.operator) if on}
        self.records.append(
            TickRecord(self.tick, [], [], [], [], started_wall=wall, operated=operated)
        )
        return out + [PublishTick(self.tick, self.tick * self.params.tick_period, snapshot)]

    def _has_everything(self) -> bool:
        present = [k for k in range(self.params.robots) if k not in self.absent]
        return (
            self.heights is not None
            and all(k in self.poses for k in present)
            and all(k in self.blades for k in present)
        )

    def _step_words(self, now: float, wall: float) -> list[TickAction]:
        n = self.params.robots
        limit = self.params.first_word_timeout if self.tick == 0 else self.params.word_timeout
        present = set(range(n)) - self.absent
        if not present <= set(self.words) and wall - self._wall < limit:
            return []
        if not self.armed:
            return []  # the words wait for the team (held: nothing moves)
        out: list[TickAction] = []
        silent = sorted(present - set(self.words))
        for k in silent:
            self.missed[k] += 1
        if silent:
            out.append(Report(f"tick {self.tick}: no word from robots {silent}; they idle"))
        words = [self.words.get(k, 0) if k in present else 0 for k in range(n)]
        self._turns = draw_turns(words, self.rng)
        self._waits = schedule(self._grid, words, self.params.reach)
        self._expected = [
            blade_setting(words[k], self._settings[k]) if self._settings[k] is not None else None
            for k in range(n)
        ]
        self._granted, self._done = {}, set()
        self._word_of = words
        record = self.records[-1]
        record.words, record.turns, record.motion_wall = words, list(self._turns), wall
        self.phase = Phase.MOTION
        return out + self._grant(now)

    def _grant(self, now: float) -> list[TickAction]:
        out: list[TickAction] = []
        if not self.armed:
            return out
        stamp = self.tick * self.params.tick_period
        for k in range(self.params.robots):
            if k in self._granted or not self._waits[k] <= self._done:
                continue
            self._granted[k] = now
            out.append(SendGoal(k, self.tick, stamp, self._word_of[k], self._turns[k]))
            if k in self.absent:  # told (its executor and the simulator keep in step), not awaited
                self._done.add(k)
        return out

    def _step_motion(self, now: float, wall: float) -> list[TickAction]:
        out: list[TickAction] = []
        for k in self.absent & set(self._granted):
            self._done.add(k)  # disabled or lost while driving: its executor has stopped it
        for k, granted in self._granted.items():
            if k not in self._done and now - granted > self.params.motion_limit:
                self._done.add(k)
                self.records[-1].late.append(k)
                self.stuck[k] = True
                self.late[k] += 1
                out.append(
                    Report(
                        f"tick {self.tick}: robot {k} did not finish within "
                        f"{self.params.motion_limit} s; the tick goes on without it"
                    )
                )
        out += self._grant(now)
        if len(self._done) < self.params.robots:
            return out
        record = self.records[-1]
        record.stuck, record.ended_wall = list(self.stuck), wall
        self.tick += 1
        self._final = self.params.steps > 0 and self.tick >= self.params.steps
        self.phase = Phase.SNAPSHOT
        self._after, self._after_wall = now, wall
        return out + self._request(wall)
