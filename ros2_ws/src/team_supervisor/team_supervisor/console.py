"""The operator's console without ROS: keys to typed actions, and the status it shows.

``ant-operator console`` (:mod:`team_supervisor.console_node`) is one process that stays
connected to the team, so an e-stop costs one service call on an open connection instead of
an interpreter's start, rclpy and discovery (3.3 s for ``ant-operator estop``). Keys:

==============  ==========================================================================
key             action
==============  ==========================================================================
space, ``e``    e-stop (always accepted, whatever else is going on)
``r``           reset the e-stop (the team is then disarmed)
``a``           arm
``p`` / ``c``   pause / resume (continue)
``0`` .. ``9``  select robot k
``t``           take the selected robot over: its executor follows the console's twists
                (zero until an arrow key), the rest of the team and its controller carry on
arrows          drive the robot taken over (forward, back, turn left, right), each press
                for :data:`HOLD` seconds, then it stands (still taken)
``h``           hand the robot back: one zero twist, then the console stops sending and
                its executor returns to the team's goals
``d`` / ``n``   disable / enable the selected robot
``q``           quit (hands back a robot it holds)
==============  ==========================================================================
"""

from __future__ import annotations

from dataclasses import dataclass, field

HOLD = 0.5
"""Seconds an arrow key drives the robot taken over (a terminal sends no key-up)."""
ARROWS = {"\x1b[A": "up", "\x1b[B": "down", "\x1b[C": "right", "\x1b[D": "left"}


@dataclass(frozen=True)
class Trigger:
    """Call the supervisor's ``~/NAME`` (std_srvs/Trigger)."""

    name: str


@dataclass(frozen=True)
class Enable:
    """Enable or disable robot ``robot`` (``/robot_K/enable``)."""

    robot: int
    on: bool


@dataclass(frozen=True)
class Take:
    """Start sending robot ``robot``'s drive override (a zero twist until an arrow key)."""

    robot: int


@dataclass(frozen=True)
class Drive:
    """The robot taken over drives at ``vx`` m/s, turning ``wz`` rad/s, for :data:`HOLD` s."""

    robot: int
    vx: float
    wz: float


@dataclass(frozen=True)
class Release:
    """Hand robot ``robot`` back to the team (one zero twist, then no more overrides)."""

    robot: int


@dataclass(frozen=True)
class Note:
    """Something to tell the operator (a key that did nothing, and why)."""

    text: str


@dataclass(frozen=True)
class Quit:
    """End the console."""


Action = Trigger | Enable | Take | Drive | Release | Note | Quit


def split_keys(data: str) -> list[str]:
    """The keys in a chunk of terminal input (an arrow is one three-character key)."""
    keys, i = [], 0
    while i < len(data):
        if data[i] == "\x1b" and data[i : i + 3] in ARROWS:
            keys.append(ARROWS[data[i : i + 3]])
            i += 3
        else:
            keys.append(data[i])
            i += 1
    return keys


@dataclass
class Console:
    """Which robot is selected and which is taken over; :meth:`key` turns a key into actions.

    Attributes:
        robots: Robots in the team (select 0 .. robots - 1).
        speed: Forward speed of an arrow key, m/s.
        turn: Turn rate of an arrow key, rad/s.
        selected: The selected robot (``None``: none).
        taken: The robot taken over (``None``: none).
    """

    robots: int
    speed: float = 0.1
    turn: float = 0.5
    selected: int | None = None
    taken: int | None = None
    triggers: dict[str, str] = field(
        default_factory=lambda: {
            " ": "estop",
            "e": "estop",
            "r": "reset",
            "a": "arm",
            "p": "pause",
            "c": "resume",
        }
    )

    def key(self, key: str) -> list[Action]:
        """The actions of one key (see the module docstring)."""
        if key in self.triggers:
            return [Trigger(self.triggers[key])]
        if key.isdigit():
            k = int(key)
            if k >= self.robots:
                return [Note(f"no robot {k} (the team has {self.robots})")]
            self.selected = k
            return [Note(f"robot {k} selected")]
        if key == "q":
            return [*self._release(), Quit()]
        if key == "h":
            return self._release() or [Note("no robot is taken over")]
        if self.selected is None and key in ("t", "d", "n", "up", "down", "left", "right"):
            return [Note("select a robot first (0-9)")]
        if key == "t":
            out = self._release() if self.taken not in (None, self.selected) else []
            self.taken = self.selected
            return [*out, Take(self.selected)]
        if key in ("d", "n"):
            return [Enable(self.selected, key == "n")]
        if key in ("up", "down", "left", "right"):
            if self.taken is None:
                return [Note("take the robot over first (t)")]
            vx = {"up": self.speed, "down": -self.speed}.get(key, 0.0)
            wz = {"left": self.turn, "right": -self.turn}.get(key, 0.0)
            return [Drive(self.taken, vx, wz)]
        return []

    def _release(self) -> list[Action]:
        if self.taken is None:
            return []
        robot, self.taken = self.taken, None
        return [Release(robot)]


def status_lines(
    robots: int,
    team: str | None,
    statuses: dict[str, tuple[int, str]],
    selected: int | None,
    taken: int | None,
) -> list[str]:
    """The console's status: the team's state, then one line per robot.

    ``statuses``: ``/diagnostics`` status name -> (level, message), the newest of each; a
    robot's line shows its executor's and blade driver's.
    """
    lines = [f"team: {team or 'no heartbeat'}"]
    for k in range(robots):
        mark = ">" if k == selected else " "
        held = " [operator]" if k == taken else ""
        parts = []
        for short, node in (("drive", "executor"), ("blade", "blade_driver")):
            level_message = statuses.get(f"/robot_{k}/{node}")
            if level_message is not None:
                parts.append(f"{short}: {level_message[1]}")
        lines.append(f"{mark} robot {k}{held}: " + ("; ".join(parts) or "no diagnostics yet"))
    return lines
