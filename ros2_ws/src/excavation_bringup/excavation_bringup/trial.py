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
final node's ``result.json``. Either way it runs ``--steps`` ticks, prints the fitness and
stops every node. ``--drive continuous`` runs drive executors, the team tick and the
continuous-motion simulator instead of the lockstep one; ``--record BAG`` records either
kind. The options become a :class:`~excavation_bringup.deployment.Deployment`, whose graph
(:mod:`excavation_bringup.graph`) one of the two launchers runs
(:mod:`excavation_bringup.launch`).
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
import re
import sys
import tempfile
import time
from dataclasses import dataclass, field

import numpy as np
from team_tick.core import TickSummary

from excavation_bringup.deployment import Deployment
from excavation_bringup.graph import Graph, build
from excavation_bringup.launch import (
    ProcessLauncher,
    RecorderThread,
    close_composed,
    compose,
)
from excavation_common.limits import MAX_ROBOTS, int_in
from excavation_sim.dynamics import WorldResult
from excavation_sim.soil import soil_arg


@dataclass
class TrialResult:
    """A trial's fitness, fitness per tick, final heights, missed and applied commands.

    ``--drive continuous`` adds the wall time of every tick (from its snapshot to the next
    tick's, the last to the end of its motion), the primitives the executors
    aborted, the stuck events (robot-ticks with U1 set), the sim time and the robots the
    team tick left out of a tick; with ``soil="physical"`` also the fine field's total
    (``soil_volume``, quanta: constant over a trial) and the robot-steps whose push the
    wheels could not give (``slips``).
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
    soil_volume: int | None = None
    slips: int = 0
    operator_ticks: dict[int, list[int]] = field(default_factory=dict)


def continuous_result(
    ticks: TickSummary, world: WorldResult, primitives_aborted: int, seconds: float, steps: int
) -> TrialResult:
    """A continuous trial's result from the team tick's summary and the ``dynamics`` world.

    Args:
        ticks: :meth:`team_tick.core.TeamTick.summary`.
        world: :meth:`excavation_sim.dynamics_node.DynamicsNode.result`.
        primitives_aborted: Summed over the executors.
        seconds: Wall time of the trial.
        steps: Ticks run (the fitness trace has one more entry).
    """
    return TrialResult(
        world.fitness,
        [world.snapshots.get(f"tick {t}", float("nan")) for t in range(steps + 1)],
        np.array(world.heights, dtype=np.int64),
        dict(ticks.missed),
        seconds,
        ticks.commands,
        holds=ticks.holds,
        tick_wall=ticks.tick_wall,
        primitives_aborted=primitives_aborted,
        stuck_events=ticks.stuck_events,
        sim_seconds=world.sim_seconds,
        robots_late=ticks.robots_late,
        soil_volume=world.volume,
        slips=world.slips,
        operator_ticks=dict(ticks.operator_ticks),
    )


def lockstep_result(data: dict, seconds: float) -> TrialResult:
    """A grid trial's result from the lockstep simulator's ``result.json``."""
    return TrialResult(
        data["fitness"],
        data["trace"],
        np.array(data["heights"], dtype=np.int64),
        {int(k): v for k, v in data["missed"].items()},
        seconds,
        data["commands"],
        data.get("holds", 0),
    )


def recorder_source(dep: Deployment) -> str:
    """The ``source`` note of a trial's bag."""
    return (
        f"ant-trial {dep.controller} robots={dep.robots} steps={dep.steps} "
        f"seed={dep.seed} blueprint={dep.blueprint} drive={dep.drive}"
    )


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
    time_factor: float = 0.0,
    soil: str = "grid",
) -> TrialResult:
    """Run a trial through the nodes and return its result.

    Args:
        controller_spec: A genome file, or ``"hand-coded"``.
        robots: Number of robots.
        steps: Ticks to run.
        seed: Scenario seed (with ``scenario`` 0: scenario 0 of ``ant-eval --seed``).
        blueprint: Blueprint spec for the server and the simulator.
        domain: ROS domain id (default: ``ROS_DOMAIN_ID`` or 0).
        command_timeout: Seconds a tick waits for every controller's word.
        timeout: Give up after this many seconds.
        blade_driver: One ``blade_driver`` node per robot between controller and simulator.
        processes: Each node in its own process instead of one composed process.
        record: Bag directory to record every suite topic into.
        perception: ``"truth"``: controllers read the simulator's poses and heights;
            ``"full"``: they read the overhead localiser's and the terrain mapper's, which
            see the simulator through its synthetic camera and laser.
        scenario: Scenario index of ``seed`` (``ScenarioSet.create(..., seed)``'s i-th).
        supervisor: ``"internal"``: the trial starts the team supervisor and arms it;
            ``"external"``: an operator's supervisor must be running, and nothing moves
            until it is armed.
        occlude: LEDs hidden from the synthetic camera (``"2:front,2:rear"``).
        drive: ``"grid"``: the lockstep simulator applies each word at once;
            ``"continuous"``: drive executors, the team tick and ``dynamics``.
        exact: ``drive="continuous"`` without slip and noise (the parity setting).
        time_factor: ``drive="continuous"``: the simulator's clock at most this many times
            real time (0: as fast as the team answers).
        soil: ``drive="continuous"``: ``"grid"`` (the world model's soil rules) or
            ``"physical"`` (a fine height field, cutting resistance and traction).

    Raises:
        TimeoutError: When the trial does not finish in time.
        RuntimeError: ``processes``: a node process failed (its log is in the message).
        ValueError: Options that cannot run together.
        ant_controller.errors.GenomeFormatError: For a bad genome file.
    """
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    if domain is None:
        domain = int(os.environ.get("ROS_DOMAIN_ID", "0"))
    dep = Deployment(
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
        exact=exact,
        soil=soil,
        processes=processes,
        time_factor=time_factor,
    )
    return run_deployment(dep)


def run_deployment(dep: Deployment, events_executor: bool = True) -> TrialResult:
    """Run the trial ``dep`` describes (its graph, by its launcher) and return its result.

    Args:
        dep: The trial.
        events_executor: A composed continuous trial spins on rclpy's
            ``experimental.EventsExecutor`` (C++ event queue) instead of the
            ``SingleThreadedExecutor``, whose wait-set rebuild per callback makes a trial of
            some 1,500 callbacks per tick about 20 times slower (docs/benchmarks.md).

    Raises:
        As :func:`run_trial`.
    """
    from ant_controller.controller import Controller

    dep.check()
    if dep.controller != "hand-coded":
        Controller.from_file(dep.controller)  # a bad genome fails before any node starts
    with tempfile.TemporaryDirectory(prefix="ant-trial-") as tmp:
        graph = build(dep, tmp)
        if dep.processes:
            return _run_processes(graph)
        if dep.drive == "continuous":
            return _run_composed_continuous(graph, events_executor)
        return _run_composed_lockstep(graph)


def _run_composed_lockstep(graph: Graph) -> TrialResult:
    """A grid trial's nodes on one executor in this process."""
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor

    from excavation_common.ros import init_rclpy

    dep = graph.deployment
    context = Context()
    init_rclpy(context=context, domain_id=dep.domain)
    executor = SingleThreadedExecutor(context=context)
    built: dict = {}
    started = time.monotonic()
    try:
        built = compose(graph, context, recorder_source(dep))
        for node in built.values():
            executor.add_node(node)
        sim = built["sim"]
        while not sim.finished:
            if time.monotonic() - started > dep.timeout:
                raise TimeoutError(f"trial did not finish within {dep.timeout} s (tick {sim.tick})")
            executor.spin_once(timeout_sec=0.05)
        recorder = built.get("recorder")
        if recorder is not None:  # the last tick's state and the controllers' answers to it
            last = time.monotonic() + graph.profile.recorder_tail
            topics = ["/clock"] + [f"/robot_{k}/behaviour" for k in range(dep.robots)]
            while time.monotonic() < last and any(
                recorder.recorded.get(t, 0) < dep.steps + 1 for t in topics
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
        close_composed(executor, built.values(), context, built.get("recorder"))


def _run_composed_continuous(graph: Graph, events_executor: bool) -> TrialResult:
    """A continuous trial's nodes on one executor (the recorder on a thread of its own)."""
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from team_tick.core import Phase

    from excavation_common.ros import init_rclpy

    dep = graph.deployment
    context = Context()
    init_rclpy(context=context, domain_id=dep.domain)
    if events_executor:
        from rclpy.experimental.events_executor import EventsExecutor

        executor = EventsExecutor(context=context)
    else:
        executor = SingleThreadedExecutor(context=context)
    built: dict = {}
    recorder = None
    started = time.monotonic()
    try:
        built = compose(graph, context, recorder_source(dep))
        if "recorder" in built:
            recorder = RecorderThread(built.pop("recorder"), context)
        for node in built.values():
            executor.add_node(node)
        tick, dynamics = built["team_tick"], built["dynamics"]
        while tick.core.phase is not Phase.FINISHED:
            if time.monotonic() - started > dep.timeout:
                raise TimeoutError(
                    f"trial did not finish within {dep.timeout} s (tick {tick.core.tick}, "
                    f"{tick.core.phase.value})"
                )
            executor.spin_once(timeout_sec=0.05)
        executors = [built[f"executor_{k}"] for k in range(dep.robots)]
        result = continuous_result(
            tick.core.summary(),
            dynamics.result(),
            sum(e.core.counters.primitives_aborted for e in executors),
            time.monotonic() - started,
            dep.steps,
        )
        if recorder is not None:  # what is still in flight
            last = time.monotonic() + graph.profile.record_tail
            while time.monotonic() < last:
                executor.spin_once(timeout_sec=0.05)
        return result
    finally:
        close_composed(executor, built.values(), context, recorder)


EXECUTOR_STATUS = re.compile(r"/robot_(\d+)/executor")


class ExecutorCounters:
    """The executors' latest ``primitives_aborted``, read from ``/diagnostics``."""

    def __init__(self, robots: int) -> None:
        self.robots = robots
        self.aborted: dict[int, int] = {}
        self.received: dict[int, float] = {}

    def on_diagnostics(self, msg) -> None:
        """Keep each executor's counter and when it arrived (wall clock)."""
        for status in msg.status:
            match = EXECUTOR_STATUS.fullmatch(status.name)
            values = {kv.key: kv.value for kv in status.values}
            if match and "primitives_aborted" in values:
                k = int(match.group(1))
                self.aborted[k] = int(values["primitives_aborted"])
                self.received[k] = time.monotonic()

    def missing_since(self, since: float) -> list[int]:
        """Robots whose executor has not reported since ``since`` (wall clock)."""
        return [k for k in range(self.robots) if self.received.get(k, -1.0) <= since]


def _run_processes(graph: Graph) -> TrialResult:
    """Every node in its own process, as separate ``ros2 run`` commands would start them.

    A grid trial's result is the lockstep simulator's ``result.json``. A continuous one's
    is the team tick's ``result.json`` (words, wall time per tick, stuck events, missed
    words) with ``dynamics``'s ``world.json`` (fitness per tick, heights) and the
    primitives the executors aborted, from their last ``/diagnostics`` report, which a
    small node of this process reads.
    """
    dep = graph.deployment
    started = time.monotonic()
    if dep.drive == "grid":
        with ProcessLauncher(graph) as trial:
            trial.start()
            data = trial.wait(dep.timeout, started)
        return lockstep_result(data, time.monotonic() - started)

    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor

    from excavation_common.ros import init_rclpy

    counters = ExecutorCounters(dep.robots)
    context = Context()
    init_rclpy(context=context, domain_id=dep.domain)
    node = rclpy.create_node("ant_trial", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    node.create_subscription(DiagnosticArray, "/diagnostics", counters.on_diagnostics, 50)
    wait = graph.profile.counters_wait
    try:
        with ProcessLauncher(graph) as trial:
            trial.start()
            ticks = trial.wait(
                dep.timeout, started, idle=lambda: executor.spin_once(timeout_sec=0.1)
            )
            ended = time.monotonic()
            while counters.missing_since(ended) and time.monotonic() < ended + wait:
                trial.check()
                executor.spin_once(timeout_sec=0.1)
            silent = counters.missing_since(ended)
            if silent:
                raise RuntimeError(
                    f"executors of robots {silent} did not report on /diagnostics "
                    f"within {wait:.0f} s of the last tick"
                )
            world = WorldResult.from_json(
                json.loads(graph.files.world.read_text()), str(graph.files.world)
            )
            if f"tick {dep.steps}" not in world.snapshots:
                raise RuntimeError(f"dynamics wrote no snapshot of tick {dep.steps}")
            seconds = time.monotonic() - started
    finally:
        executor.remove_node(node)
        node.destroy_node()
        executor.shutdown()
        rclpy.try_shutdown(context=context)
    return continuous_result(
        TickSummary.from_json(ticks, str(graph.files.result)),
        world,
        sum(counters.aborted.values()),
        seconds,
        dep.steps,
    )


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
    p.add_argument(
        "--timeout",
        type=int_in(1, 10**7),
        default=None,
        help="s after which the trial gives up (default: 600, or 10 s per tick when more)",
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
    p.add_argument(
        "--soil",
        type=soil_arg,
        default="grid",
        help="--drive continuous: grid (the world model's soil rules), physical (the fine "
        "soil calibrated to the grid), physical:dome or physical:lunar (the paper's two "
        "real worlds), each optionally followed by ,KEY=VALUE soil parameters",
    )
    p.add_argument("--json", action="store_true")
    args = p.parse_args(argv)
    from excavation_common.errors import FieldError
    from excavation_common.signals import interrupt_on_sigint, keep_interrupts

    interrupt_on_sigint()  # Ctrl-C stops it even when a script started it in the background

    try:
        with keep_interrupts():
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
                command_timeout=args.command_timeout
                or (30.0 if args.perception == "full" else 2.0),
                timeout=args.timeout or max(600.0, 10.0 * args.steps),
                drive=args.drive,
                exact=args.no_slip,
                soil=args.soil,
            )
    except (FieldError, TimeoutError, RuntimeError, ValueError) as exc:
        print(f"ant-trial: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("ant-trial: interrupted: the trial's nodes are closed", file=sys.stderr)
        return 130
    extra = {}
    if args.drive == "continuous":
        extra = {
            "wall_per_tick": result.tick_wall,
            "primitives_aborted": result.primitives_aborted,
            "stuck_events": result.stuck_events,
            "sim_seconds": result.sim_seconds,
            "robots_late": result.robots_late,
            "operator_ticks": {str(k): t for k, t in result.operator_ticks.items()},
        }
        if result.soil_volume is not None:
            extra |= {"soil_volume": result.soil_volume, "slips": result.slips}
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
        for k, ticks in sorted(result.operator_ticks.items()):
            print(f"robot {k}: driven by the operator in ticks {ticks}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
