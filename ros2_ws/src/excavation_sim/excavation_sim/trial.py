"""``ant-trial``: one excavation trial through the ROS nodes, in one process.

Starts the blueprint server, the lockstep simulator and one controller per robot (composed
on one executor, the way ``executors/composed.py`` of ros2/examples composes nodes; this
environment has no launch), runs ``--steps`` ticks, prints the fitness and stops every node.
The result equals ``ant-eval --scenarios 1`` with the same seed (``tests/test_trial.py``).

Examples::

    ant-trial --genome genomes/best.json --robots 4 --steps 300 --seed 0
    ant-trial --hand-coded --robots 1 --blueprint site.yaml

Traffic stays on this machine when ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` (set here
unless already set); ``--domain`` picks the ROS domain (default: ``ROS_DOMAIN_ID`` or 0).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from dataclasses import dataclass

import numpy as np


@dataclass
class TrialResult:
    """A trial's fitness, fitness per tick, final heights, missed and applied commands."""

    fitness: float
    trace: list[float]
    heights: np.ndarray
    missed: dict[int, int]
    seconds: float
    commands: list[list[int]]


def run_trial(
    controller_spec: str,
    robots: int,
    steps: int,
    seed: int,
    blueprint: str = "default",
    domain: int | None = None,
    command_timeout: float = 2.0,
    timeout: float = 600.0,
) -> TrialResult:
    """Run a trial through the nodes and return its result.

    Args:
        controller_spec: A genome file, or ``"hand-coded"``.
        robots: Number of robots.
        steps: Ticks to run.
        seed: Scenario seed (scenario 0 of ``ant-eval --seed``).
        blueprint: Blueprint spec for the server and the simulator.
        domain: ROS domain id (default: ``ROS_DOMAIN_ID`` or 0).
        command_timeout: Seconds the simulator waits for a command.
        timeout: Give up after this many seconds.

    Raises:
        TimeoutError: When the trial does not finish in time.
        ant_controller.errors.GenomeFormatError: For a bad genome file.
    """
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter

    from ant_controller.controller import Controller
    from ant_controller.controller_node import ControllerNode
    from blueprint_server.server_node import BlueprintServer
    from excavation_sim.sim_node import SimNode

    ctl = (
        Controller.hand_coded()
        if controller_spec == "hand-coded"
        else Controller.from_file(controller_spec)
    )
    if domain is None:
        domain = int(os.environ.get("ROS_DOMAIN_ID", "0"))
    context = Context()
    rclpy.init(context=context, domain_id=domain)
    executor = SingleThreadedExecutor(context=context)
    nodes = []
    started = time.monotonic()
    try:
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
                Parameter("command_timeout", value=float(command_timeout)),
            ],
        )
        nodes.append(sim)
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
        for node in nodes:
            executor.add_node(node)
        while not sim.finished:
            if time.monotonic() - started > timeout:
                raise TimeoutError(f"trial did not finish within {timeout} s (tick {sim.tick})")
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
        for node in nodes:
            executor.remove_node(node)
            node.destroy_node()
        executor.shutdown()
        rclpy.try_shutdown(context=context)


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
    p.add_argument("--domain", type=int, default=None)
    p.add_argument("--json", action="store_true")
    args = p.parse_args(argv)
    from ant_controller.errors import FieldError

    try:
        result = run_trial(
            "hand-coded" if args.hand_coded else args.genome,
            args.robots,
            args.steps,
            args.seed,
            args.blueprint,
            args.domain,
        )
    except (FieldError, TimeoutError) as exc:
        print(f"ant-trial: error: {exc}", file=sys.stderr)
        return 2
    if args.json:
        print(
            json.dumps(
                {"fitness": result.fitness, "missed": result.missed, "seconds": result.seconds}
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
