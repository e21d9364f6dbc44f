"""``ant-trial``: one excavation trial through the ROS nodes.

Starts the team supervisor, the blueprint server, the lockstep simulator, and per robot a
controller and a blade driver (``--no-blade-driver`` leaves the drivers out; the simulator
then publishes the blade's joint state itself). The supervisor is armed at start
(``--supervisor internal``, the default), or the trial waits for an operator to run one and
arm it (``--supervisor external``: ``ant-operator arm``); either way ``ant-operator`` can
pause, e-stop, disable robots and override blades while the trial runs, and a paused trial
resumes and ends as an unpaused one does (docs/operator.md). By default the nodes are
composed on one executor in one process (the way ``executors/composed.py`` of ros2/examples
composes nodes; this environment has no launch); ``--processes`` starts each node as its own
process, as separate ``ros2 run`` commands would, and collects the result from the
simulator's ``result_file``. Either way it runs ``--steps`` ticks, prints the fitness and
stops every node. ``--drive continuous`` runs drive executors, the team tick and the
continuous-motion simulator instead of the lockstep one
(:mod:`excavation_bringup.continuous_trial`; with ``--processes``
:mod:`excavation_bringup.continuous_processes`); ``--record BAG`` records either kind.
The result equals ``ant-eval --scenarios 1`` with the same seed (``tests/test_trial.py``).

Examples::

    ant-trial --genome genomes/best.json --robots 4 --steps 300 --seed 0
    ant-trial --hand-coded --robots 1 --blueprint site.yaml --processes

Traffic stays on this machine when ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` (set here
unless already set); ``--domain`` picks the ROS domain (default: ``ROS_DOMAIN_ID`` or 0).
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from excavation_common.limits import MAX_ROBOTS, int_in
from excavation_common.middleware import use_profiles


@dataclass
class TrialResult:
    """A trial's fitness, fitness per tick, final heights, missed and applied commands.

    ``--drive continuous`` adds the wall time of every tick (from its snapshot to the next
    tick's, the last to the end of its motion), the primitives the executors
    aborted, the stuck events (robot-ticks with U1 set), the sim time and the robots the
    team tick left out of a tick.
    """

    fitness: float
    trace: list[float]
    heights: np.ndarray
    missed: dict[int, int]
    seconds: float
    commands: list[list[int]]
    holds: int = 0
    tick_wall: list[float] = field(default_factory=list)
    primitives_aborted: int = 0
    stuck_events: int = 0
    sim_seconds: float = 0.0
    robots_late: int = 0


@dataclass(frozen=True)
class TrialSpec:
    """What one trial runs (the arguments of :func:`run_trial`, resolved)."""

    controller: str
    robots: int
    steps: int
    seed: int
    blueprint: str
    scenario: int
    domain: int
    command_timeout: float
    timeout: float
    blade_driver: bool
    record: str | None
    perception: str
    supervisor: str = "internal"
    occlude: str = ""
    drive: str = "grid"


LOST_TIMEOUT = 1.5
"""Seconds of pose stamps (1.5 ticks) after which the trial's supervisor stops a silent robot:
more than one tick, since the poses of one tick arrive one after another."""
LOST_GRACE = 2.0
"""Further seconds (2 ticks) before a lost robot is disabled for the rest of the trial."""


def _supervisor_params(robots: int, armed: bool, watch_poses: bool | None = None) -> dict:
    """The trial's supervisor parameters (``watch_poses``: the node's default when None)."""
    values = {
        "robots": robots,
        "lost_timeout": LOST_TIMEOUT,
        "lost_grace": LOST_GRACE,
        "arm_at_start": armed,
    }
    if watch_poses is not None:
        values["watch_poses"] = watch_poses
    return values


def _lockstep_watches_poses(spec: TrialSpec) -> bool:
    """Whether a lockstep trial's supervisor runs the lost-robot policy.

    Only with ``perception="full"``, where the localizer can lose a robot. With truth
    perception the simulator publishes every robot's pose of a tick together, so no robot
    can be lost; the policy could only misjudge one from the order in which a busy
    supervisor takes the poses of a trial running faster than real time.
    """
    return spec.perception == "full"


def close_composed(executor, nodes, context, recorder=None) -> None:
    """Tear a composed trial down: close its bag, destroy its nodes, shut its context."""
    import rclpy

    if recorder is not None:
        recorder.close()
    for node in nodes:
        executor.remove_node(node)
        node.destroy_node()
    executor.shutdown()
    rclpy.try_shutdown(context=context)


def _controller_args(controller_spec: str) -> list[str]:
    return ["--hand-coded"] if controller_spec == "hand-coded" else ["--genome", controller_spec]


def run_trial(
    controller_spec: str,
    robots: int,
    steps: int,
    seed: int,
    blueprint: str = "default",
    domain: int | None = None,
    command_timeout: float = 2.0,
    timeout: float = 600.0,
    blade_driver: bool = True,
    processes: bool = False,
    record: str | None = None,
    perception: str = "truth",
    scenario: int = 0,
    supervisor: str = "internal",
    occlude: str = "",
    drive: str = "grid",
    exact: bool = False,
) -> TrialResult:
    """Run a trial through the nodes and return its result.

    Args:
        controller_spec: A genome file, or ``"hand-coded"``.
        robots: Number of robots.
        steps: Ticks to run.
        seed: Scenario seed (with ``scenario`` 0: scenario 0 of ``ant-eval --seed``).
        blueprint: Blueprint spec for the server and the simulator.
        domain: ROS domain id (default: ``ROS_DOMAIN_ID`` or 0).
        command_timeout: Seconds the simulator waits for a command.
        timeout: Give up after this many seconds.
        blade_driver: One ``blade_driver`` node per robot between controller and simulator.
        processes: Each node in its own process instead of one composed process.
        record: Bag directory to record every suite topic into (``ant-bag record``'s
            recorder node on the same executor, or its own process).
        perception: ``"truth"``: controllers read the simulator's poses and heights;
            ``"full"``: they read the overhead localizer's and the terrain mapper's, which
            see the simulator through its synthetic camera and laser
            (:mod:`excavation_bringup.perception`).
        scenario: Scenario index of ``seed`` (``ScenarioSet.create(..., seed)``'s i-th).
        supervisor: ``"internal"``: the trial starts the team supervisor and arms it;
            ``"external"``: an operator's supervisor (``ros2 run team_supervisor
            supervisor``) must be running, and nothing moves until it is armed.
        occlude: The sensors node's ``occlude`` (``"2:front,2:rear"`` hides robot 2 from
            the camera; ``perception="full"`` only).
        drive: ``"grid"``: the lockstep simulator applies each word at once; ``"continuous"``:
            drive executors, the team tick and the ``dynamics`` simulator
            (:mod:`excavation_bringup.continuous_trial`, with ``processes``
            :mod:`excavation_bringup.continuous_processes`).
        exact: ``drive="continuous"`` without slip and noise (the parity setting).

    Raises:
        TimeoutError: When the trial does not finish in time.
        RuntimeError: ``processes``: a node process failed (its log is in the message).
        ant_controller.errors.GenomeFormatError: For a bad genome file.
    """
    from ant_controller.controller import Controller

    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    ctl = (
        Controller.hand_coded()
        if controller_spec == "hand-coded"
        else Controller.from_file(controller_spec)
    )
    if domain is None:
        domain = int(os.environ.get("ROS_DOMAIN_ID", "0"))
    if perception not in ("truth", "full"):
        raise ValueError(f"perception = {perception!r}: expected 'truth' or 'full'")
    if supervisor not in ("internal", "external"):
        raise ValueError(f"supervisor = {supervisor!r}: expected 'internal' or 'external'")
    if occlude and perception != "full":
        raise ValueError("occlude: hides a robot from the camera, so needs perception 'full'")
    if drive not in ("grid", "continuous"):
        raise ValueError(f"drive = {drive!r}: expected 'grid' or 'continuous'")
    spec = TrialSpec(
        controller_spec,
        robots,
        steps,
        seed,
        blueprint,
        scenario,
        domain,
        command_timeout,
        timeout,
        blade_driver,
        record,
        perception,
        supervisor,
        occlude,
        drive,
    )
    if drive == "continuous" and processes:
        from excavation_bringup.continuous_processes import run_continuous_processes

        return run_continuous_processes(spec, exact=exact)
    if drive == "continuous":
        from excavation_bringup.continuous_trial import run_continuous

        return run_continuous(ctl, spec, exact=exact)
    return _run_processes(spec) if processes else _run_composed(ctl, spec)


PERCEPTION_SIM = {"truth_prefix": "/truth", "wait_for_ready": True}
"""The simulator's parameters with ``--perception full``: the true state moves aside, and
tick 0 waits for every controller's ``ready`` (its side of each input connected; the
sensors node holds a frame until the localizer's subscription is matched)."""


def _recorder_source(spec: TrialSpec) -> str:
    return (
        f"ant-trial {spec.controller} robots={spec.robots} steps={spec.steps} "
        f"seed={spec.seed} blueprint={spec.blueprint} drive={spec.drive}"
    )


def trial_recorder(context, spec: TrialSpec):
    """The bag recorder of a composed trial (``ant-bag record``'s node) on ``context``."""
    from rclpy.parameter import Parameter

    from blueprint_server.blueprint import resolve_blueprint
    from excavation_bags.recorder_node import RecorderNode

    return RecorderNode(
        custom_data={"source": _recorder_source(spec)},
        context=context,
        parameter_overrides=[
            Parameter("out", value=str(spec.record)),
            Parameter("height_unit", value=float(resolve_blueprint(spec.blueprint).height_unit)),
        ],
    )


def recorder_command(spec: TrialSpec, height_unit: float) -> list[str]:
    """The bag recorder of a trial as a process (``ant-bag record --out BAG``)."""
    return [
        sys.executable,
        "-m",
        "excavation_bags.cli",
        "record",
        "--out",
        str(spec.record),
        "--height-unit",
        repr(float(height_unit)),
    ]


def node_command(name: str, module: str, *args: str, ns: str = "", remaps=(), **params):
    """``python -m module ARGS --ros-args`` naming the node ``name`` in ``ns``.

    Args:
        name: Node name (``-r __node:=name``).
        module: The node's module (run by this interpreter, as ``ros2 run`` would).
        *args: Arguments before ``--ros-args``.
        ns: Namespace, or empty.
        remaps: Further ``from:=to`` remappings.
        **params: ROS parameters (``-p name:=value``).
    """
    cmd = [sys.executable, "-m", module, *args, "--ros-args", "-r", f"__node:={name}"]
    if ns:
        cmd += ["-r", f"__ns:={ns}"]
    for remap in remaps:
        cmd += ["-r", remap]
    for key, value in params.items():
        cmd += ["-p", f"{key}:={_ros_value(value)}"]
    return cmd


def _run_composed(ctl, spec: TrialSpec) -> TrialResult:
    """All nodes on one executor in this process."""
    robots, steps, seed = spec.robots, spec.steps, spec.seed
    blueprint, domain, timeout, perception = (
        spec.blueprint,
        spec.domain,
        spec.timeout,
        spec.perception,
    )
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter

    from ant_controller.controller_node import ControllerNode
    from blade_driver.driver_node import BladeDriverNode
    from blueprint_server.server_node import BlueprintServer
    from excavation_sim.sim_node import SimNode
    from team_supervisor.supervisor_node import SupervisorNode

    context = Context()
    from excavation_common.ros import init_rclpy

    init_rclpy(context=context, domain_id=domain)
    executor = SingleThreadedExecutor(context=context)
    nodes = []
    recorder = None
    started = time.monotonic()
    try:
        if spec.record:  # first, so that it sees every topic appear
            recorder = trial_recorder(context, spec)
            nodes.append(recorder)
        if spec.supervisor == "internal":
            values = _supervisor_params(robots, True, _lockstep_watches_poses(spec))
            nodes.append(
                SupervisorNode(
                    context=context,
                    parameter_overrides=[Parameter(k, value=v) for k, v in values.items()],
                )
            )
        nodes.append(
            BlueprintServer(
                context=context, parameter_overrides=[Parameter("blueprint", value=blueprint)]
            )
        )
        sim = SimNode(
            context=context,
            parameter_overrides=[
                Parameter("blueprint", value=blueprint),
                Parameter("robots", value=robots),
                Parameter("steps", value=steps),
                Parameter("seed", value=seed),
                Parameter("scenario", value=spec.scenario),
                Parameter("command_timeout", value=float(spec.command_timeout)),
                Parameter("blade_driver", value=spec.blade_driver),
            ]
            + (
                [Parameter(name, value=value) for name, value in PERCEPTION_SIM.items()]
                if perception == "full"
                else []
            ),
        )
        nodes.append(sim)
        if perception == "full":
            from excavation_bringup.perception import perception_nodes

            nodes += perception_nodes(context, robots, seed, sim.blueprint, spec.occlude)
        height_unit = sim.blueprint.height_unit
        for k in range(robots):
            nodes.append(
                ControllerNode(
                    ctl,
                    context=context,
                    namespace=f"/robot_{k}",
                    parameter_overrides=[
                        Parameter("robot_id", value=k),
                        Parameter("robots", value=robots),
                        Parameter("height_unit", value=height_unit),
                        Parameter("lockstep", value=True),
                    ],
                )
            )
            if spec.blade_driver:
                nodes.append(BladeDriverNode(context=context, namespace=f"/robot_{k}"))
        for node in nodes:
            executor.add_node(node)
        while not sim.finished:
            if time.monotonic() - started > timeout:
                raise TimeoutError(f"trial did not finish within {timeout} s (tick {sim.tick})")
            executor.spin_once(timeout_sec=0.05)
        if recorder is not None:  # the last tick's state and the controllers' answers to it
            last = time.monotonic() + 5.0
            topics = ["/clock"] + [f"/robot_{k}/behaviour" for k in range(robots)]
            while time.monotonic() < last and any(
                recorder.recorded.get(t, 0) < steps + 1 for t in topics
            ):
                executor.spin_once(timeout_sec=0.05)
        return TrialResult(
            sim.world.fitness(),
            list(sim.fitness_trace),
            sim.world.heights.copy(),
            dict(sim.missed),
            time.monotonic() - started,
            list(sim.applied),
            sim.holds,
        )
    finally:
        close_composed(executor, nodes, context, recorder)


def _ros_value(value) -> str:
    """``value`` as a ``-p name:=value`` argument (parsed as YAML by rcl)."""
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, float):
        return repr(value)
    if value == "":
        return '""'  # rcl cannot parse an empty value; YAML's empty string
    return str(value)


def process_commands(spec: TrialSpec, workdir: Path) -> dict[str, list[str]]:
    """Each node's command line for ``spec``, in start order (name -> argv).

    What separate ``ros2 run`` commands would start: the recorder first (``record``), the
    team supervisor (armed; none when the operator runs their own), the blueprint server,
    the simulator (writing ``workdir/result.json`` at the end; with a recorder, tick 0 waits
    for it), with ``perception="full"``
    the sensors, localizer (its camera calibration written to ``workdir/camera.yaml`` now)
    and mapper, then per robot a controller and a blade driver.
    """
    from blueprint_server.blueprint import resolve_blueprint

    bp = resolve_blueprint(spec.blueprint)
    height_unit = bp.height_unit
    full = spec.perception == "full"

    node = node_command
    commands: dict[str, list[str]] = {}
    if spec.record:
        commands["recorder"] = recorder_command(spec, height_unit)
    if spec.supervisor == "internal":
        commands["supervisor"] = node(
            "supervisor",
            "team_supervisor.supervisor_node",
            **_supervisor_params(spec.robots, True, _lockstep_watches_poses(spec)),
        )
    commands["server"] = node("server", "blueprint_server.server_node", blueprint=spec.blueprint)
    commands["sim"] = node(
        "sim",
        "excavation_sim.sim_node",
        blueprint=spec.blueprint,
        robots=spec.robots,
        steps=spec.steps,
        seed=spec.seed,
        scenario=spec.scenario,
        command_timeout=float(spec.command_timeout),
        blade_driver=spec.blade_driver,
        result_file=str(Path(workdir) / "result.json"),
        wait_for_recorder=bool(spec.record),
        **(PERCEPTION_SIM if full else {}),
    )
    if full:
        from excavation_bringup.perception import perception_parameters

        values = perception_parameters(
            spec.robots,
            spec.seed,
            bp,
            str(Path(workdir) / "camera.yaml"),
            spec.occlude,
            processes=True,
        )
        commands["sensors"] = node("sensors", "excavation_sim.sensors_node", **values["sensors"])
        commands["localizer"] = node(
            "localizer", "overhead_localizer.localizer_node", **values["localizer"]
        )
        commands["mapper"] = node("mapper", "terrain_mapper.mapper_node", **values["mapper"])
    for k in range(spec.robots):
        commands[f"controller_{k}"] = node(
            "controller",
            "ant_controller.controller_node",
            *_controller_args(spec.controller),
            ns=f"/robot_{k}",
            robot_id=k,
            robots=spec.robots,
            height_unit=float(height_unit),
            lockstep=True,
        )
        if spec.blade_driver:
            commands[f"blade_driver_{k}"] = node(
                "blade_driver", "blade_driver.driver_node", ns=f"/robot_{k}", backend="sim"
            )
    return commands


class TrialProcesses:
    """A trial's nodes as processes: start, watch, kill and restart them, read the result.

    ``ant-trial --processes`` starts them all and waits for the simulator; the fault tests
    (``tests/faults.py``) and ``ant-soak`` also kill and restart single nodes. Each node's
    output goes to ``workdir/NAME.log`` (appended across restarts).

    Args:
        spec: The trial.
        workdir: Folder for logs, the calibration and ``result.json``.
        env: Environment of the nodes (default: this one); ``ROS_DOMAIN_ID`` is the spec's.
        commands: The node commands (default: :func:`process_commands` of ``spec``).
        final: The node whose exit ends the trial and which writes ``result.json`` (the
            lockstep ``sim``; the continuous trial's ``team_tick``).
    """

    def __init__(
        self,
        spec: TrialSpec,
        workdir: str | Path,
        env: dict | None = None,
        commands: dict[str, list[str]] | None = None,
        final: str = "sim",
    ) -> None:
        self.spec = spec
        self.workdir = Path(workdir)
        self.workdir.mkdir(parents=True, exist_ok=True)
        self.commands = commands if commands is not None else process_commands(spec, self.workdir)
        self.final = final
        self.env = dict(env if env is not None else os.environ, ROS_DOMAIN_ID=str(spec.domain))
        self.env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
        use_profiles(self.env)  # the nodes' middleware settings (excavation_common.middleware)
        self.procs: dict[str, subprocess.Popen] = {}
        self.result_file = self.workdir / "result.json"

    def log(self, name: str) -> Path:
        """The log file of node ``name``."""
        return self.workdir / f"{name}.log"

    def start(self, name: str | None = None, command: list[str] | None = None, **popen) -> None:
        """Start node ``name`` (default: every node, in order), with ``command`` if given."""
        if name is None:
            for n in self.commands:
                self.start(n)
            return
        cmd = command or self.commands[name]
        with open(self.log(name), "ab") as out:
            self.procs[name] = subprocess.Popen(
                cmd, env=self.env, stdout=out, stderr=subprocess.STDOUT, **popen
            )

    def kill(self, name: str, sig: int = signal.SIGKILL) -> int:
        """Send ``sig`` to node ``name``, wait for it and forget it; returns its exit code."""
        proc = self.procs.pop(name)
        if proc.poll() is None:
            proc.send_signal(sig)
        return proc.wait()

    def check(self) -> None:
        """Raise when a node exited by itself with an error.

        Raises:
            RuntimeError: Naming the node, its exit code and the end of its log.
        """
        for name, proc in self.procs.items():
            if proc.poll() is not None and proc.returncode != 0:
                log = _tail(self.log(name))
                raise RuntimeError(f"{name} exited with {proc.returncode}:\n{log}")

    @property
    def finished(self) -> bool:
        """The final node ended (after its last tick, or by a failure)."""
        final = self.procs.get(self.final)
        return final is not None and final.poll() is not None

    def wait(self, timeout: float, started: float | None = None, idle=None) -> dict:
        """Wait for the final node to end and return its result (``result.json``).

        Args:
            timeout: Seconds from ``started`` (default: now) to give up after.
            started: ``time.monotonic()`` of the trial's start.
            idle: Called instead of sleeping 0.1 s between checks (a trial spinning a
                node of its own), or ``None``.

        Raises:
            TimeoutError: Not finished within ``timeout`` seconds of ``started``.
            RuntimeError: A node failed, or the final node wrote no result.
        """
        started = time.monotonic() if started is None else started
        while not self.finished:
            if time.monotonic() - started > timeout:
                raise TimeoutError(f"trial did not finish within {timeout} s")
            self.check()
            if idle is None:
                time.sleep(0.1)
            else:
                idle()
        final = self.procs[self.final]
        if final.returncode != 0 or not self.result_file.exists():
            log = _tail(self.log(self.final))
            raise RuntimeError(f"{self.final} exited with {final.returncode}:\n{log}")
        return json.loads(self.result_file.read_text())

    def stop(self) -> None:
        """Stop every node as Ctrl-C would; the recorder last, so that the bag is complete."""
        recorder = {n: p for n, p in self.procs.items() if n == "recorder"}
        _stop({n: p for n, p in self.procs.items() if n != "recorder"})
        _stop(recorder)
        self.procs.clear()

    def __enter__(self) -> TrialProcesses:
        return self

    def __exit__(self, *exc) -> None:
        self.stop()


def _run_processes(spec: TrialSpec) -> TrialResult:
    """Every node in its own process, as separate ``ros2 run`` commands would start them."""
    started = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="ant-trial-") as tmp:
        with TrialProcesses(spec, tmp) as trial:
            trial.start()
            data = trial.wait(spec.timeout, started)
    return TrialResult(
        data["fitness"],
        data["trace"],
        np.array(data["heights"], dtype=np.int64),
        {int(k): v for k, v in data["missed"].items()},
        time.monotonic() - started,
        data["commands"],
        data.get("holds", 0),
    )


def _tail(log: Path, lines: int = 20) -> str:
    return "\n".join(log.read_text(errors="replace").splitlines()[-lines:])


def _stop(procs: dict[str, subprocess.Popen]) -> None:
    """SIGINT every node still running (as Ctrl-C would), then kill what is left."""
    for proc in procs.values():
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
    deadline = time.monotonic() + 10.0
    for proc in procs.values():
        try:
            proc.wait(timeout=max(0.1, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


MAX_TRIAL_STEPS = 100_000
"""Most ticks of one trial (ant-trial's limits; docs/reliability.md lists them all)."""
MAX_TRIAL_SCENARIO = 100_000
MAX_COMMAND_TIMEOUT = 3600.0
MAX_DOMAIN = 232


def _timeout(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not 0 < value <= MAX_COMMAND_TIMEOUT:  # also refuses NaN
        raise argparse.ArgumentTypeError(
            f"{value} s is outside (0, {MAX_COMMAND_TIMEOUT:g}] (the limit)"
        )
    return value


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``ant-trial``."""
    p = argparse.ArgumentParser(prog="ant-trial", description=__doc__.split("\n\n")[0])
    who = p.add_mutually_exclusive_group(required=True)
    who.add_argument("--genome", metavar="FILE")
    who.add_argument("--hand-coded", action="store_true")
    p.add_argument("--robots", type=int_in(1, MAX_ROBOTS), default=4)
    p.add_argument("--blueprint", default="default")
    p.add_argument("--steps", type=int_in(1, MAX_TRIAL_STEPS), default=300)
    p.add_argument("--seed", type=int_in(0, 2**63 - 1), default=0)
    p.add_argument(
        "--scenario", type=int_in(0, MAX_TRIAL_SCENARIO), default=0, help="scenario index of --seed"
    )
    p.add_argument(
        "--command-timeout",
        type=_timeout,
        default=None,
        help="s the simulator waits per tick (default 2; 30 with --perception full, whose "
        "camera and laser rendering takes a loaded machine seconds per tick)",
    )
    p.add_argument("--domain", type=int_in(0, MAX_DOMAIN), default=None)
    p.add_argument(
        "--no-blade-driver",
        action="store_true",
        help="no blade_driver nodes (sim publishes the blade)",
    )
    p.add_argument("--processes", action="store_true", help="each node in its own process")
    p.add_argument("--record", metavar="BAG", help="record every topic into this bag directory")
    p.add_argument(
        "--perception",
        choices=("truth", "full"),
        default="truth",
        help="full: controllers see the sim only through the camera+localizer, laser+mapper",
    )
    p.add_argument(
        "--supervisor",
        choices=("internal", "external"),
        default="internal",
        help="internal: start the team supervisor armed; external: wait for an operator's "
        "(ant-operator arm)",
    )
    p.add_argument(
        "--occlude",
        default="",
        metavar="K:front,K:rear",
        help="hide LEDs from the camera (--perception full), e.g. 2:front,2:rear",
    )
    p.add_argument(
        "--drive",
        choices=("grid", "continuous"),
        default="grid",
        help="continuous: drive executors, team tick and the continuous-motion simulator",
    )
    p.add_argument(
        "--no-slip", action="store_true", help="--drive continuous without slip and noise"
    )
    p.add_argument("--json", action="store_true")
    args = p.parse_args(argv)
    from excavation_common.errors import FieldError

    try:
        result = run_trial(
            "hand-coded" if args.hand_coded else args.genome,
            args.robots,
            args.steps,
            args.seed,
            args.blueprint,
            args.domain,
            blade_driver=not args.no_blade_driver,
            processes=args.processes,
            record=args.record,
            perception=args.perception,
            scenario=args.scenario,
            supervisor=args.supervisor,
            occlude=args.occlude,
            command_timeout=args.command_timeout or (30.0 if args.perception == "full" else 2.0),
            drive=args.drive,
            exact=args.no_slip,
        )
    except (FieldError, TimeoutError, RuntimeError, ValueError) as exc:
        print(f"ant-trial: error: {exc}", file=sys.stderr)
        return 2
    extra = {}
    if args.drive == "continuous":
        extra = {
            "wall_per_tick": result.tick_wall,
            "primitives_aborted": result.primitives_aborted,
            "stuck_events": result.stuck_events,
            "sim_seconds": result.sim_seconds,
            "robots_late": result.robots_late,
        }
    if args.json:
        print(
            json.dumps(
                {
                    "fitness": result.fitness,
                    "missed": result.missed,
                    "seconds": result.seconds,
                    "holds": result.holds,
                }
                | extra
            )
        )
    else:
        print(
            f"trial through the nodes: fitness {result.fitness:.4f} after {args.steps} ticks "
            f"({result.seconds:.1f} s, missed commands: {sum(result.missed.values())})"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
