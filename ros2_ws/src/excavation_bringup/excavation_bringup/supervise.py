"""The process supervisor as a pure state machine: start order, restarts, ordered shutdown.

:class:`Supervisor` knows no processes: the runner (:class:`excavation_bringup.launch.
ProcessLauncher`) tells it what happened (a node reported on ``/diagnostics``, a process
exited, a stop was asked for) and carries out the actions :meth:`Supervisor.poll` returns,
one small frozen dataclass per kind (:class:`Start`, :class:`Stop`, :class:`Kill`,
:class:`Report`). ``docs/dome.md`` describes the policy; ``tests/test_dome_supervisor.py``
runs it without a process.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class RestartPolicy:
    """How the supervisor starts, restarts and stops its children.

    Attributes:
        backoff: Seconds before the first restart of a crashed node.
        factor: Each further restart waits this many times longer ...
        max_backoff: ... up to this many seconds.
        max_restarts: Restarts of one node before the run gives up.
        stable_after: A node up this long has its restart count reset.
        ready_timeout: Seconds a starting node has to report on ``/diagnostics``.
        stop_timeout: Seconds a stopping node has to exit before it is killed.
    """

    backoff: float = 1.0
    factor: float = 2.0
    max_backoff: float = 30.0
    max_restarts: int = 5
    stable_after: float = 60.0
    ready_timeout: float = 120.0
    stop_timeout: float = 10.0

    def delay(self, restarts: int) -> float:
        """Back-off before restart number ``restarts + 1``."""
        return min(self.backoff * self.factor**restarts, self.max_backoff)


IDLE, STARTING, UP, BACKOFF, STOPPING, STOPPED = (
    "idle",
    "starting",
    "up",
    "backoff",
    "stopping",
    "stopped",
)
ALIVE = (STARTING, UP, STOPPING)


@dataclass
class Child:
    """A supervised node's state (see :class:`Supervisor`)."""

    name: str
    restart: bool = True
    final: bool = False
    state: str = IDLE
    restarts: int = 0
    since: float = 0.0
    next_start: float = 0.0
    stop_sent: float = 0.0
    killed: bool = False
    exit_code: int | None = None


@dataclass(frozen=True)
class Start:
    """Start node ``name``'s process."""

    name: str


@dataclass(frozen=True)
class Stop:
    """Ask node ``name`` to stop (SIGINT, as Ctrl-C would)."""

    name: str


@dataclass(frozen=True)
class Kill:
    """Kill node ``name`` (it outlived ``stop_timeout``)."""

    name: str


@dataclass(frozen=True)
class Report:
    """A line for the run's ``events.log``."""

    text: str


Action = Start | Stop | Kill | Report
"""What the supervisor asks of the process runner."""


def control_reports(statuses, last: dict[str, str]) -> list[Report]:
    """The operator's actions a round of ``/diagnostics`` statuses names, each once.

    A console (``ant-operator console``, the live view) names its newest action in its
    status's ``last_control`` value; ``last`` keeps what each status said before (updated
    here). Returns a :class:`Report` per new action, with its origin.
    """
    out = []
    for s in statuses:
        values = {v.key: v.value for v in s.values}
        action = values.get("last_control")
        if action and last.get(s.name) != action:
            last[s.name] = action
            out.append(Report(f"operator: {action} ({s.name})"))
    return out


@dataclass
class Supervisor:
    """Start order, readiness, restarts with back-off and ordered shutdown, without processes.

    The runner tells it what happened (:meth:`ready`, :meth:`exited`, :meth:`stop`) and
    carries out the :class:`Action` list :meth:`poll` returns. Start-up: children start one
    at a time in order, each after the one before it is ``up`` (reported on
    ``/diagnostics``). A crash: back-off and restart (a ``final`` child exiting with 0 ends
    the run; exit code 2, an unrestartable child, too many restarts or a node that never
    reports end it as failed). Shutdown: children stop one at a time in reverse order, each
    killed if it outlives ``stop_timeout``.
    """

    children: list[Child]
    policy: RestartPolicy = field(default_factory=RestartPolicy)
    phase: str = "starting"
    failure: str = ""
    finished: bool = False
    _pending: list[Action] = field(default_factory=list)

    @classmethod
    def create(cls, specs: list, policy: RestartPolicy | None = None) -> Supervisor:
        """A supervisor for node specs in start order (``name``, ``restart``, ``final``)."""
        return cls([Child(s.name, s.restart, s.final) for s in specs], policy or RestartPolicy())

    def child(self, name: str) -> Child:
        """The child called ``name``."""
        return next(c for c in self.children if c.name == name)

    @property
    def done(self) -> bool:
        """Every child has stopped after a shutdown."""
        return self.phase == "done"

    def _report(self, text: str) -> None:
        self._pending.append(Report(text))

    def _start(self, c: Child, now: float) -> Action:
        c.state, c.since, c.exit_code, c.killed = STARTING, now, None, False
        return Start(c.name)

    def ready(self, name: str, now: float) -> None:
        """``name`` reported on ``/diagnostics``."""
        c = self.child(name)
        if c.state == STARTING:
            c.state, c.since = UP, now
            self._report(f"{name} is up" + (f" again (restart {c.restarts})" if c.restarts else ""))

    def stop(self, now: float, reason: str, failed: bool = False) -> None:
        """Begin the ordered shutdown (idempotent)."""
        if self.phase in ("stopping", "done"):
            return
        if failed and not self.failure:
            self.failure = reason
        self.phase = "stopping"
        self._report(f"stopping: {reason}")
        for c in self.children:
            if c.state in (IDLE, BACKOFF):
                c.state = STOPPED

    def exited(self, name: str, code: int, now: float) -> None:
        """``name``'s process ended with ``code``."""
        c = self.child(name)
        c.exit_code = code
        if c.state == STOPPING or self.phase in ("stopping", "done"):
            if c.state != STOPPING and c.state in ALIVE:
                self._report(f"{name} exited with code {code} during shutdown")
            c.state = STOPPED
            return
        if c.final and code == 0:
            c.state = STOPPED
            self.finished = True
            self._report(f"{name} finished")
            self.stop(now, f"{name} finished")
            return
        was_up = c.state == UP
        if was_up and now - c.since >= self.policy.stable_after:
            c.restarts = 0
        self._report(f"{name} exited with code {code}")
        if code == 2:
            c.state = STOPPED
            self.stop(now, f"{name} refused its configuration (exit code 2): see its log", True)
        elif not c.restart:
            c.state = STOPPED
            self.stop(now, f"{name} crashed and is not restartable", True)
        elif c.restarts >= self.policy.max_restarts:
            c.state = STOPPED
            self.stop(now, f"{name} crashed {c.restarts + 1} times: giving up", True)
        else:
            delay = self.policy.delay(c.restarts)
            c.restarts += 1
            c.state, c.next_start = BACKOFF, now + delay
            self._report(f"restarting {name} in {delay:.1f} s (restart {c.restarts})")

    def poll(self, now: float) -> list[Action]:
        """The actions due at ``now``."""
        actions = self._pending
        self._pending = []
        if self.phase == "starting":
            for c in self.children:
                if c.state == UP:
                    continue
                if c.state == IDLE:
                    actions.append(self._start(c, now))
                break
            if all(c.state == UP for c in self.children):
                self.phase = "running"
                actions.append(Report(f"all {len(self.children)} nodes are up"))
        if self.phase in ("starting", "running"):
            for c in self.children:
                if c.state == BACKOFF and now >= c.next_start:
                    actions.append(self._start(c, now))
                elif c.state == STARTING and now - c.since > self.policy.ready_timeout:
                    self.stop(
                        now,
                        f"{c.name} did not report on /diagnostics within "
                        f"{self.policy.ready_timeout:.0f} s",
                        True,
                    )
                    actions += self._pending
                    self._pending = []
                    break
        if self.phase == "stopping":
            alive = [c for c in reversed(self.children) if c.state in ALIVE]
            if not alive:
                self.phase = "done"
                actions.append(Report("every node has stopped"))
            else:
                c = alive[0]
                if c.state != STOPPING:
                    c.state, c.stop_sent = STOPPING, now
                    actions.append(Stop(c.name))
                elif not c.killed and now - c.stop_sent > self.policy.stop_timeout:
                    c.killed = True
                    actions.append(Kill(c.name))
                    actions.append(Report(f"{c.name} did not stop: killed"))
        return actions
