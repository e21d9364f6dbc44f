"""``ant-dome``: check a site file, and bring the dome up from it (paper, 6).

``ant-dome check SITE [--sim]`` prints every inconsistency of a site file
(:mod:`excavation_bringup.site`), one per line as ``file: field = value: reason``, and
exits 1 if there is any.

``ant-dome up SITE [--sim] [--record BAG] [--view]`` generates every node's parameters from
the site file and starts each node as its own process (the venv's interpreter,
``python -m module``, as ``ros2 run`` would), in the order of :func:`node_table`, each one
only after the one before it has reported on ``/diagnostics``. A node that crashes is
restarted with exponential back-off and reported; a node that exits with code 2 (a bad
parameter or file: it would fail again), exhausts its restarts or is not restartable ends
the run. Every node logs into ``RUN/logs/NAME.log``; ``RUN/events.log`` has the
supervisor's reports and ``RUN/state.json`` each node's pid, state and restarts. Ctrl-C
(SIGINT) or SIGTERM stops the nodes one by one in reverse order (the bag recorder, started
first, stops last and finishes the bag).

In the dome (no ``--sim``) the table is the hardware's: the team supervisor first,
DISARMED (nothing moves until ``ant-operator arm``), the blueprint server, the localiser and
the mapper on the site's camera and laser, one blade driver per robot on its board (a tick's
blade bits after the tick's drive: ``blade_after_motion``), one drive executor per robot
(closing its loop on the localiser's ``/robot_k/pose``, its ``cmd_vel`` remapped to the
robot's ``drive_topic``: the base), the controllers (lockstep, on the team tick's ``/tick``
topics) and the team tick, which turns their words into goals for the executors, robot by
robot, and runs until Ctrl-C (``--ticks N``: N ticks, then the run ends). Every node runs on
the wall clock.

``--sim`` puts the continuous-motion simulator in place of the dome's hardware, as
``ant-trial --drive continuous --perception full --processes`` runs it: ``dynamics`` (the
robots' bases and the clock: every other node runs on ``use_sim_time``), one drive
executor per robot closing its loop on the simulator's truth, the synthetic camera and
laser (``sensors``, rendering the simulator's snapshot after each tick's motion), the
simulator as every robot's blade board (the blade drivers' ``sim`` backend), and the team
tick, which runs the site's ticks (``--ticks``) and ends the run; the localizer and the
mapper see only the synthetic sensors. The fitness is printed.

Examples::

    ant-dome check ros2_ws/src/excavation_bringup/config/site_dome.yaml
    ant-dome up ros2_ws/src/excavation_bringup/config/site_sim.yaml --sim --view
    ant-dome up my_dome.yaml --record bags/trial_01 --view
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from excavation_bringup import site as sitefile
from excavation_common.files import write_text_atomic
from excavation_common.middleware import use_profiles

# --- the node table -------------------------------------------------------------------------


@dataclass(frozen=True)
class NodeSpec:
    """One process of the dome.

    Attributes:
        name: Unique label (log file, state, reports), e.g. ``controller_1``.
        module: ``python -m`` module of the node.
        params: ROS parameters (written to ``RUN/params/NAME.yaml``).
        diagnostics: ``/diagnostics`` status names (or prefixes ending in ``*``) that show
            the node is up.
        args: Command-line arguments before ``--ros-args``.
        namespace: ROS namespace (``/robot_k``), or empty.
        restart: Restart it when it crashes.
        final: Its exit with code 0 ends the run (the team tick after its ticks).
        remaps: Topic remappings ``from:=to``.
    """

    name: str
    module: str
    params: dict[str, Any]
    diagnostics: tuple[str, ...]
    args: tuple[str, ...] = ()
    namespace: str = ""
    restart: bool = True
    final: bool = False
    remaps: tuple[str, ...] = ()

    def command(self, params_file: str | Path) -> list[str]:
        """The command line that starts it (the venv's interpreter)."""
        cmd = [sys.executable, "-m", self.module, *self.args, "--ros-args"]
        if self.namespace:
            cmd += ["-r", f"__ns:={self.namespace}"]
        for remap in self.remaps:
            cmd += ["-r", remap]
        return cmd + ["--params-file", str(params_file)]

    def reports(self, status_name: str) -> bool:
        """True when a ``/diagnostics`` status of this name comes from this node."""
        for name in self.diagnostics:
            if status_name == name or (name.endswith("*") and status_name.startswith(name[:-1])):
                return True
        return False


WORLD_FILE = "world.json"
"""``--sim``: the simulator's world at every snapshot (fitness, heights)."""
RESULT_FILE = "result.json"
"""``--sim``: the team tick's summary after its last tick (words, missed, wall per tick)."""


def simulator(site: sitefile.Site, run_dir: Path) -> list[NodeSpec]:
    """What ``--sim`` puts in place of the robots: ``dynamics`` and one executor per robot.

    They start first: ``dynamics`` is the clock of every other node (``use_sim_time``),
    and it starts stepping once every executor is on the graph, so that the timers of the
    nodes after them run. Nothing moves before the supervisor arms the team and the team
    tick grants a goal. ``dynamics`` is not restartable (a new one would start the world
    over); a restarted executor has lost the goal it was driving, and the team tick goes on
    without that robot once ``motion_limit`` has passed.
    """
    dynamics = NodeSpec(
        "dynamics",
        "excavation_sim.dynamics_node",
        sitefile.dynamics_params(site, str(run_dir / WORLD_FILE)),
        ("/dynamics",),
        restart=False,
    )
    return [dynamics, *executors(site, sim=True)]


def executors(site: sitefile.Site, sim: bool) -> list[NodeSpec]:
    """One drive executor per robot (lifecycle: each configures and activates itself).

    With ``--sim`` on the simulator's truth and clock; in the dome on the localiser's pose,
    on the wall clock, its ``cmd_vel`` remapped to the robot's ``drive_topic`` (the base).
    """
    return [
        NodeSpec(
            f"executor_{k}",
            "drive_executor.executor_node",
            {
                **sitefile.executor_params(site, k, sim),
                **(sitefile.SIM_CLOCK if sim else {}),
            },
            (f"/{robot.name}/executor",),
            namespace=f"/{robot.name}",
            remaps=() if sim else tuple(sitefile.executor_remaps(site, k)),
        )
        for k, robot in enumerate(site.robots)
    ]


def team_tick(
    site: sitefile.Site, run_dir: Path, ticks: int, sim: bool = True, record: bool = False
) -> NodeSpec:
    """The team tick: last, and its exit after ``ticks`` ticks ends the run (0: never).

    With ``record`` its tick 0 waits for the recorder (the bag then holds every tick).

    Not restartable: a new one would start the ticks over.
    """
    return NodeSpec(
        "team_tick",
        "team_tick.node",
        {
            **sitefile.team_tick_params(site, ticks, str(run_dir / RESULT_FILE), sim, record),
            **(sitefile.SIM_CLOCK if sim else {}),
        },
        ("/team_tick",),
        restart=False,
        final=ticks > 0,
    )


def synthetic_sensors(site: sitefile.Site) -> NodeSpec:
    """The overhead camera and laser ``--sim`` renders from the simulator's truth."""
    return NodeSpec(
        "sensors",
        "excavation_sim.sensors_node",
        {**sitefile.sensors_params(site), **sitefile.SIM_CLOCK},
        ("/sensors",),
    )


def node_table(
    site: sitefile.Site,
    run_dir: Path,
    sim: bool = False,
    record: str | None = None,
    view: bool = False,
    ticks: int | None = None,
    view_port: int = 8765,
) -> list[NodeSpec]:
    """Every process of the dome, in start order (stopped in reverse).

    Writes the files the nodes read into ``run_dir`` (the site's LED table, and with
    ``sim`` the simulated camera's calibration).
    """
    from excavation_bringup.perception import simulated_calibration

    run_dir.mkdir(parents=True, exist_ok=True)
    beacons = run_dir / "beacons.yaml"
    write_text_atomic(beacons, yaml.safe_dump(sitefile.beacons_document(site), sort_keys=False))
    calibration = site.camera.calibration
    if calibration == sitefile.SIMULATED:
        from blueprint_server.blueprint import resolve_blueprint
        from overhead_localizer.camera_model import save_model

        calibration = str(run_dir / "camera.yaml")
        save_model(
            simulated_calibration(resolve_blueprint(site.worksite.blueprint), site.sim.seed),
            calibration,
        )
    clock = sitefile.SIM_CLOCK if sim else {}
    table: list[NodeSpec] = []
    if record:
        table.append(
            NodeSpec(
                "recorder",
                "excavation_bags.cli",
                sitefile.recorder_params(site, record),
                ("/bag_recorder",),
                args=("record", "--out", str(record)),
                restart=False,  # a second recorder cannot reopen the bag
            )
        )
    if sim:
        table += simulator(site, run_dir)
    table.append(
        NodeSpec(
            "supervisor",
            "team_supervisor.supervisor_node",
            {**sitefile.supervisor_params(site, sim), **clock},
            ("/supervisor",),
        )
    )
    table.append(
        NodeSpec(
            "server",
            "blueprint_server.server_node",
            {**sitefile.server_params(site), **clock},
            ("/blueprint_server", "blueprint_server: *"),
        )
    )
    if sim:
        table.append(synthetic_sensors(site))
    table.append(
        NodeSpec(
            "localizer",
            "overhead_localizer.localizer_node",
            {
                **sitefile.localizer_params(site, calibration, str(beacons), reliable=sim),
                **({"annotated_period": 0.5} if view else {}),
                **clock,
            },
            ("/localizer", "localizer: *"),
        )
    )
    table.append(
        NodeSpec(
            "mapper",
            "terrain_mapper.mapper_node",
            {**sitefile.mapper_params(site, reliable=sim), **clock},
            ("/mapper", "mapper"),
        )
    )
    for k, robot in enumerate(site.robots):
        ns = f"/{robot.name}"
        table.append(
            NodeSpec(
                f"blade_driver_{k}",
                "blade_driver.driver_node",
                {**sitefile.blade_driver_params(site, k, sim, after_motion=True), **clock},
                (f"{ns}/blade_driver",),
                namespace=ns,
            )
        )
    if not sim:
        table += executors(site, sim=False)
    for k, robot in enumerate(site.robots):
        ns = f"/{robot.name}"
        table.append(
            NodeSpec(
                f"controller_{k}",
                "ant_controller.controller_node",
                {**sitefile.controller_params(site, k), **clock},
                (f"{ns}/controller",),
                args=tuple(sitefile.controller_args(site, k)),
                namespace=ns,
                remaps=tuple(sitefile.controller_remaps(site, k, sim)),
            )
        )
    ticks = (ticks or site.sim.ticks) if sim else (ticks or 0)
    table.append(team_tick(site, run_dir, ticks, sim, record=bool(record)))
    if view:
        table.append(
            NodeSpec(
                "view",
                "excavation_bringup.view",
                {},
                ("/ant_view",),
                args=(
                    "--site",
                    str(Path(site.path).resolve()),
                    "--calibration",
                    str(calibration),
                    "--port",
                    str(view_port),
                ),
            )
        )
    return table


# --- the supervisor (pure) ----------------------------------------------------------------


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
class Action:
    """What the supervisor asks of the process runner: ``start``, ``stop``, ``kill``, ``report``."""

    kind: str
    name: str = ""
    text: str = ""


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
    def create(cls, specs: list[NodeSpec], policy: RestartPolicy | None = None) -> Supervisor:
        """A supervisor for the node table ``specs``."""
        return cls([Child(s.name, s.restart, s.final) for s in specs], policy or RestartPolicy())

    def child(self, name: str) -> Child:
        """The child called ``name``."""
        return next(c for c in self.children if c.name == name)

    @property
    def done(self) -> bool:
        """Every child has stopped after a shutdown."""
        return self.phase == "done"

    def _report(self, text: str) -> None:
        self._pending.append(Action("report", text=text))

    def _start(self, c: Child, now: float) -> Action:
        c.state, c.since, c.exit_code, c.killed = STARTING, now, None, False
        return Action("start", c.name)

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
                actions.append(Action("report", text=f"all {len(self.children)} nodes are up"))
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
                actions.append(Action("report", text="every node has stopped"))
            else:
                c = alive[0]
                if c.state != STOPPING:
                    c.state, c.stop_sent = STOPPING, now
                    actions.append(Action("stop", c.name))
                elif not c.killed and now - c.stop_sent > self.policy.stop_timeout:
                    c.killed = True
                    actions.append(Action("kill", c.name))
                    actions.append(Action("report", text=f"{c.name} did not stop: killed"))
        return actions


# --- the runner -----------------------------------------------------------------------------


class Dome:
    """Runs a node table as processes under a :class:`Supervisor` (see the module docstring)."""

    def __init__(
        self,
        specs: list[NodeSpec],
        run_dir: Path,
        env: dict[str, str],
        policy: RestartPolicy | None = None,
        echo: bool = True,
    ) -> None:
        """Prepare ``run_dir`` (params, logs) for ``specs`` started with ``env``."""
        self.specs = {s.name: s for s in specs}
        self.run_dir = run_dir
        self.env = dict(os.environ, **env)
        use_profiles(self.env)  # the nodes' middleware settings (excavation_common.middleware)
        self.supervisor = Supervisor.create(specs, policy)
        self.procs: dict[str, subprocess.Popen] = {}
        self.echo = echo
        self.stop_requested = ""
        (run_dir / "params").mkdir(parents=True, exist_ok=True)
        (run_dir / "logs").mkdir(parents=True, exist_ok=True)
        self.events = open(run_dir / "events.log", "a", encoding="utf-8")  # noqa: SIM115
        for spec in specs:
            doc = {"/**": {"ros__parameters": spec.params}} if spec.params else {}
            write_text_atomic(self.params_file(spec.name), yaml.safe_dump(doc, sort_keys=False))

    def params_file(self, name: str) -> Path:
        """``RUN/params/NAME.yaml``."""
        return self.run_dir / "params" / f"{name}.yaml"

    def report(self, text: str) -> None:
        """One line into ``events.log`` (and on stdout)."""
        line = f"{time.strftime('%H:%M:%S')} {text}"
        self.events.write(line + "\n")
        self.events.flush()
        if self.echo:
            print(f"ant-dome: {text}", flush=True)

    def write_state(self) -> None:
        """``RUN/state.json``: each node's pid, state, restarts and last exit code."""
        state = {
            c.name: {
                "pid": self.procs[c.name].pid if c.name in self.procs else None,
                "state": c.state,
                "restarts": c.restarts,
                "exit_code": c.exit_code,
            }
            for c in self.supervisor.children
        }
        write_text_atomic(self.run_dir / "state.json", json.dumps(state, indent=1))

    def _start(self, name: str) -> None:
        spec = self.specs[name]
        log = open(self.run_dir / "logs" / f"{name}.log", "ab")  # noqa: SIM115
        log.write(f"--- {time.strftime('%Y-%m-%d %H:%M:%S')} start\n".encode())
        log.flush()
        self.procs[name] = subprocess.Popen(
            spec.command(self.params_file(name)),
            env=self.env,
            stdout=log,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            start_new_session=True,  # Ctrl-C reaches the dome only: it stops them in order
        )
        log.close()

    def _signal(self, name: str, sig: int) -> None:
        proc = self.procs.get(name)
        if proc is not None and proc.poll() is None:
            proc.send_signal(sig)

    def request_stop(self, reason: str) -> None:
        """Ask for the ordered shutdown (from a signal handler: only a flag is set)."""
        self.stop_requested = reason

    def run(self, timeout: float | None = None) -> bool:
        """Start, supervise and finally stop every node; True unless the run failed.

        Args:
            timeout: Stop (as failed) after this many seconds; ``None``: run until the
                simulator finishes or a signal arrives.
        """
        import rclpy
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions

        sup = self.supervisor
        context = Context()
        from excavation_common.ros import init_rclpy

        init_rclpy(
            context=context,
            domain_id=int(self.env["ROS_DOMAIN_ID"]),
            signal_handler_options=SignalHandlerOptions.NO,
        )
        node = rclpy.create_node("ant_dome", context=context)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        seen: list[str] = []
        node.create_subscription(
            DiagnosticArray, "/diagnostics", lambda m: seen.extend(s.name for s in m.status), 50
        )
        started = time.monotonic()
        try:
            while not sup.done:
                now = time.monotonic()
                if self.stop_requested:
                    sup.stop(now, self.stop_requested)
                    self.stop_requested = ""
                if timeout is not None and now - started > timeout:
                    sup.stop(now, f"timed out after {timeout:.0f} s", failed=True)
                for name in set(seen):
                    for spec in self.specs.values():
                        if spec.reports(name):
                            sup.ready(spec.name, now)
                seen.clear()
                for name, proc in list(self.procs.items()):
                    code = proc.poll()
                    if code is not None:
                        del self.procs[name]
                        sup.exited(name, code, now)
                changed = False
                for action in sup.poll(now):
                    changed = True
                    if action.kind == "start":
                        self._start(action.name)
                        self.report(f"starting {action.name} (pid {self.procs[action.name].pid})")
                    elif action.kind == "stop":
                        self.report(f"stopping {action.name}")
                        self._signal(action.name, signal.SIGINT)
                    elif action.kind == "kill":
                        self._signal(action.name, signal.SIGKILL)
                    else:
                        self.report(action.text)
                if changed:
                    self.write_state()
                executor.spin_once(timeout_sec=0.05)
        finally:
            for name in list(self.procs):  # only after an exception: nothing may outlive us
                self._signal(name, signal.SIGKILL)
                self.procs[name].wait()
            self.write_state()
            executor.remove_node(node)
            node.destroy_node()
            executor.shutdown()
            rclpy.try_shutdown(context=context)
            self.events.close()
        return not sup.failure


# --- command line ---------------------------------------------------------------------------


def cmd_check(args: argparse.Namespace) -> int:
    """``ant-dome check``."""
    site, errors = sitefile.check_site(args.site, sim=args.sim)
    for e in errors:
        print(str(e))
    if errors:
        print(f"ant-dome: {len(errors)} problem(s) in {args.site}", file=sys.stderr)
        return 1
    print(
        f"ant-dome: {args.site} is consistent ({site.n_robots} robots, domain "
        f"{site.network.domain}, {'simulated' if args.sim else 'dome'} hardware)"
    )
    return 0


def sim_result(run_dir: Path) -> dict | None:
    """A ``--sim`` run's result: the team tick's summary with the world's fitness and heights.

    ``None`` until the team tick has finished (or when the simulator wrote no world).
    """
    ticks, world = run_dir / RESULT_FILE, run_dir / WORLD_FILE
    if not (ticks.exists() and world.exists()):
        return None
    data = json.loads(world.read_text())
    return json.loads(ticks.read_text()) | {"fitness": data["fitness"], "heights": data["heights"]}


def cmd_up(args: argparse.Namespace) -> int:
    """``ant-dome up``."""
    site, errors = sitefile.check_site(args.site, sim=args.sim)
    if errors:
        for e in errors:
            print(f"ant-dome: error: {e}", file=sys.stderr)
        return 2
    run_dir = Path(args.run_dir or Path("dome_runs") / time.strftime("%Y%m%d-%H%M%S")).resolve()
    record = str(Path(args.record).resolve()) if args.record else None
    specs = node_table(site, run_dir, args.sim, record, args.view, args.ticks, args.view_port)
    env = sitefile.environment(site, args.domain)
    dome = Dome(specs, run_dir, env, echo=not args.json)
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda s, _f: dome.request_stop(signal.Signals(s).name))
    dome.report(
        f"bringing up {args.site} ({len(specs)} nodes, domain {env['ROS_DOMAIN_ID']}) in {run_dir}"
    )
    ok = dome.run(timeout=args.timeout)
    result = sim_result(run_dir) if args.sim else None
    summary = {
        "ok": ok,
        "run_dir": str(run_dir),
        "failure": dome.supervisor.failure,
        "restarts": {c.name: c.restarts for c in dome.supervisor.children if c.restarts},
        "fitness": result["fitness"] if result else None,
        "ticks": len(result["commands"]) if result else None,
        "bag": record,
    }
    if args.json:
        print(json.dumps(summary))
    else:
        if result:
            print(f"ant-dome: fitness {result['fitness']:.4f} after {summary['ticks']} ticks")
        if record:
            print(f"ant-dome: bag {record} (ant-bag report {record} --out REPORT)")
        if not ok:
            print(f"ant-dome: failed: {dome.supervisor.failure}", file=sys.stderr)
    return 0 if ok else 1


def parser() -> argparse.ArgumentParser:
    """The command line."""
    p = argparse.ArgumentParser(
        prog="ant-dome",
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="\n\n".join(__doc__.split("\n\n")[1:]),
    )
    sub = p.add_subparsers(dest="command", required=True)
    c = sub.add_parser("check", help="name every inconsistency of a site file")
    c.add_argument("site", metavar="SITE")
    c.add_argument("--sim", action="store_true", help="check it for ant-dome up --sim")
    c.set_defaults(run=cmd_check)
    u = sub.add_parser("up", help="bring the dome up from a site file")
    u.add_argument("site", metavar="SITE")
    u.add_argument("--sim", action="store_true", help="the simulator in place of the hardware")
    u.add_argument("--record", metavar="BAG", help="record every suite topic into this bag")
    u.add_argument("--view", action="store_true", help="serve the live view (ant-view)")
    u.add_argument("--view-port", type=int, default=8765)
    u.add_argument(
        "--ticks",
        type=int,
        default=None,
        help="ticks to run (default: with --sim the site's; the dome until Ctrl-C)",
    )
    u.add_argument("--domain", type=int, default=None, help="ROS domain (default: the site's)")
    u.add_argument("--run-dir", metavar="DIR", help="default dome_runs/<date-time>")
    u.add_argument("--timeout", type=float, default=None, help="give up after S seconds")
    u.add_argument("--json", action="store_true", help="print the outcome as JSON")
    u.set_defaults(run=cmd_up)
    return p


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``ant-dome``."""
    args = parser().parse_args(argv)
    return args.run(args)


if __name__ == "__main__":
    sys.exit(main())
