"""``ant-trial``: one excavation trial through the ROS nodes.

Starts the blueprint server, the lockstep simulator, and per robot a controller and a blade
driver (``--no-blade-driver`` leaves the drivers out; the simulator then publishes the
blade's joint state itself). By default the nodes are composed on one executor in one
process (the way ``executors/composed.py`` of ros2/examples composes nodes; this
environment has no launch); ``--processes`` starts each node as its own process, as
separate ``ros2 run`` commands would, and collects the result from the simulator's
``result_file``. Either way it runs ``--steps`` ticks, prints the fitness and stops every
node. The result equals ``ant-eval --scenarios 1`` with the same seed (``tests/test_trial.py``).

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
    drive: str = "grid"


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
            recorder node on the same executor; composed mode only).
        perception: ``"truth"``: controllers read the simulator's poses and heights;
            ``"full"``: they read the overhead localizer's and the terrain mapper's, which
            see the simulator through its synthetic camera and laser
            (:mod:`excavation_bringup.perception`; composed mode only).
        scenario: Scenario index of ``seed`` (``ScenarioSet.create(..., seed)``'s i-th).
        drive: ``"grid"``: the lockstep simulator applies each word at once; ``"continuous"``:
            drive executors, the team tick and the ``dynamics`` simulator
            (:mod:`excavation_bringup.continuous_trial`; composed mode only).
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
    if record and processes:
        raise ValueError("record: the recorder runs in the composed mode (without processes)")
    if perception not in ("truth", "full"):
        raise ValueError(f"perception = {perception!r}: expected 'truth' or 'full'")
    if perception == "full" and processes:
        raise ValueError("perception: full runs in the composed mode (without processes)")
    if drive not in ("grid", "continuous"):
        raise ValueError(f"drive = {drive!r}: expected 'grid' or 'continuous'")
    if drive == "continuous" and processes:
        raise ValueError("drive: continuous runs in the composed mode (without processes)")
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
        drive,
    )
    if drive == "continuous":
        from excavation_bringup.continuous_trial import run_continuous

        return run_continuous(ctl, spec, exact=exact)
    return _run_processes(spec) if processes else _run_composed(ctl, spec)


def _run_composed(ctl, spec: TrialSpec) -> TrialResult:
    """All nodes on one executor in this process."""
    controller_spec, robots, steps, seed = spec.controller, spec.robots, spec.steps, spec.seed
    blueprint, domain, timeout, perception = (
        spec.blueprint,
        spec.domain,
        spec.timeout,
        spec.perception,
    )
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter

    from ant_controller.controller_node import ControllerNode
    from blade_driver.driver_node import BladeDriverNode
    from blueprint_server.server_node import BlueprintServer
    from excavation_sim.sim_node import SimNode

    context = Context()
    rclpy.init(context=context, domain_id=domain)
    executor = SingleThreadedExecutor(context=context)
    nodes = []
    recorder = None
    started = time.monotonic()
    try:
        if spec.record:  # first, so that it sees every topic appear
            from blueprint_server.blueprint import resolve_blueprint
            from excavation_bags.recorder_node import RecorderNode

            recorder = RecorderNode(
                custom_data={
                    "source": f"ant-trial {controller_spec} robots={robots} "
                    f"steps={steps} seed={seed} blueprint={blueprint}"
                },
                context=context,
                parameter_overrides=[
                    Parameter("out", value=str(spec.record)),
                    Parameter("height_unit", value=float(resolve_blueprint(blueprint).height_unit)),
                ],
            )
            nodes.append(recorder)
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
            + ([Parameter("truth_prefix", value="/truth")] if perception == "full" else []),
        )
        nodes.append(sim)
        if perception == "full":
            from excavation_bringup.perception import perception_nodes

            nodes += perception_nodes(context, robots, seed, sim.blueprint)
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
        )
    finally:
        if recorder is not None:
            recorder.close()
        for node in nodes:
            executor.remove_node(node)
            node.destroy_node()
        executor.shutdown()
        rclpy.try_shutdown(context=context)


def _run_processes(spec: TrialSpec) -> TrialResult:
    """Every node in its own process, as separate ``ros2 run`` commands would start them."""
    controller_spec, robots, steps, seed = spec.controller, spec.robots, spec.steps, spec.seed
    blueprint, domain, timeout, blade_driver = (
        spec.blueprint,
        spec.domain,
        spec.timeout,
        spec.blade_driver,
    )
    command_timeout, scenario = spec.command_timeout, spec.scenario
    from blueprint_server.blueprint import resolve_blueprint

    env = dict(os.environ, ROS_DOMAIN_ID=str(domain))
    height_unit = resolve_blueprint(blueprint).height_unit
    started = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="ant-trial-") as tmp:
        result_file = Path(tmp) / "result.json"

        def node(name: str, module: str, *args: str) -> list[str]:
            return [sys.executable, "-m", module, *args, "--ros-args", "-r", f"__node:={name}"]

        commands = {
            "server": node("server", "blueprint_server.server_node")
            + ["-p", f"blueprint:={blueprint}"],
            "sim": node("sim", "excavation_sim.sim_node")
            + [
                "-p",
                f"blueprint:={blueprint}",
                "-p",
                f"robots:={robots}",
                "-p",
                f"steps:={steps}",
                "-p",
                f"seed:={seed}",
                "-p",
                f"scenario:={scenario}",
                "-p",
                f"command_timeout:={float(command_timeout)!r}",
                "-p",
                f"blade_driver:={str(blade_driver).lower()}",
                "-p",
                f"result_file:={result_file}",
            ],
        }
        for k in range(robots):
            commands[f"controller_{k}"] = node(
                "controller", "ant_controller.controller_node", *_controller_args(controller_spec)
            ) + [
                "-r",
                f"__ns:=/robot_{k}",
                "-p",
                f"robot_id:={k}",
                "-p",
                f"robots:={robots}",
                "-p",
                f"height_unit:={float(height_unit)!r}",
                "-p",
                "lockstep:=true",
            ]
            if blade_driver:
                commands[f"blade_driver_{k}"] = node("blade_driver", "blade_driver.driver_node") + [
                    "-r",
                    f"__ns:=/robot_{k}",
                    "-p",
                    "backend:=sim",
                ]
        procs: dict[str, tuple[subprocess.Popen, Path]] = {}
        try:
            for name, cmd in commands.items():
                log = Path(tmp) / f"{name}.log"
                with open(log, "wb") as out:
                    procs[name] = (
                        subprocess.Popen(cmd, env=env, stdout=out, stderr=subprocess.STDOUT),
                        log,
                    )
            sim = procs["sim"][0]
            while sim.poll() is None:
                if time.monotonic() - started > timeout:
                    raise TimeoutError(f"trial did not finish within {timeout} s")
                for name, (proc, log) in procs.items():
                    if proc.poll() is not None and proc.returncode != 0:
                        raise RuntimeError(f"{name} exited with {proc.returncode}:\n{_tail(log)}")
                time.sleep(0.1)
            if sim.returncode != 0 or not result_file.exists():
                raise RuntimeError(f"sim exited with {sim.returncode}:\n{_tail(procs['sim'][1])}")
            data = json.loads(result_file.read_text())
        finally:
            _stop(procs)
    return TrialResult(
        data["fitness"],
        data["trace"],
        np.array(data["heights"], dtype=np.int64),
        {int(k): v for k, v in data["missed"].items()},
        time.monotonic() - started,
        data["commands"],
    )


def _tail(log: Path, lines: int = 20) -> str:
    return "\n".join(log.read_text(errors="replace").splitlines()[-lines:])


def _stop(procs: dict) -> None:
    """SIGINT every node still running (as Ctrl-C would), then kill what is left."""
    for proc, _ in procs.values():
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
    deadline = time.monotonic() + 10.0
    for proc, _ in procs.values():
        try:
            proc.wait(timeout=max(0.1, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``ant-trial``."""
    p = argparse.ArgumentParser(prog="ant-trial", description=__doc__.split("\n\n")[0])
    who = p.add_mutually_exclusive_group(required=True)
    who.add_argument("--genome", metavar="FILE")
    who.add_argument("--hand-coded", action="store_true")
    p.add_argument("--robots", type=int, default=4)
    p.add_argument("--blueprint", default="default")
    p.add_argument("--steps", type=int, default=300)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--scenario", type=int, default=0, help="scenario index of --seed")
    p.add_argument(
        "--command-timeout",
        type=float,
        default=None,
        help="s the simulator waits per tick (default 2; 30 with --perception full, whose "
        "camera and laser rendering takes a loaded machine seconds per tick)",
    )
    p.add_argument("--domain", type=int, default=None)
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
                {"fitness": result.fitness, "missed": result.missed, "seconds": result.seconds}
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
