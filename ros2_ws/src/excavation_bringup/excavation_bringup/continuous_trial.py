"""``ant-trial --drive continuous``: executors, team tick and ``dynamics`` in one trial.

Composed on one executor in one process (as ``ant-trial``'s default mode): the blueprint
server; the ``dynamics`` simulator (the clock: every other node runs on ``use_sim_time``);
per robot a controller (lockstep mode, remapped onto the team tick's ``/tick`` topics), a
blade driver (sim backend) and a drive executor (lifecycle: configured and activated here);
the team tick; and the team supervisor, armed at start (``ant-operator`` can e-stop, pause,
disable or override it as in any trial). With ``perception="full"`` the controllers see the
site only through the synthetic camera + localiser and laser + mapper, which render the
dynamics' snapshots
(``/snapshot``); the executors close their loop on the simulator's per-step pose
(``/truth/robot_k/pose``), which stands in for a localiser running at camera rate.

With ``exact`` physics (no slip, no noise) the result equals the lockstep grid trial's and
``ant-eval``'s (tests/test_continuous_trial.py): moves are the world model's own, random
turns come from the world's stream (the team tick draws them), and conflicting robots move
in robot-index order.

Oversight (docs/operator.md): the supervisor's lost-robot policy watches ``/robot_k/pose``
and each executor's ``drive/status`` (:class:`team_supervisor.team.Team`); the team tick
leaves a disabled or lost robot out and holds while the team is not armed; a pause
suspends the executors' goals, so a paused trial resumed ends as an unpaused one.
``supervisor="external"`` starts none: run ``ros2 run team_supervisor supervisor`` with
``use_sim_time`` and arm it (and a ``time_factor``, so that its heartbeat keeps up).
"""

from __future__ import annotations

import time

from excavation_bringup.trial import TrialResult, TrialSpec

TICK_PREFIX = "/tick"
SNAPSHOT_PREFIX = "/snapshot"
TRUTH_PREFIX = "/truth"
IDLE_TIME_FACTOR = 10.0
"""The simulator's clock runs at most 10 x real time while the team stands still (the
controllers decide, a snapshot is rendered): otherwise it races through those waits,
spending the CPU they need."""


def controller_remaps(robot: int, robots: int) -> list[str]:
    """``cli_args`` that point a lockstep controller at the team tick's snapshot topics."""
    args = ["--ros-args"]
    for j in range(robots):
        args += ["-r", f"/robot_{j}/pose:={TICK_PREFIX}/robot_{j}/pose"]
    args += ["-r", f"/worksite/height_map:={TICK_PREFIX}/worksite/height_map"]
    args += ["-r", f"/robot_{robot}/stuck:={TICK_PREFIX}/robot_{robot}/stuck"]
    return args


def run_continuous(
    ctl,
    spec: TrialSpec,
    exact: bool = False,
    events_executor: bool = True,
    time_factor: float = 0.0,
    fault=None,
) -> TrialResult:
    """Run the trial of ``spec`` through executors, team tick and ``dynamics``.

    Args:
        ctl: The :class:`ant_controller.controller.Controller`.
        spec: What to run (``blade_driver`` must be true: the blade drivers are part of it).
        exact: No slip and no noise (the parity setting); otherwise the documented defaults.
        events_executor: Spin on rclpy's ``experimental.EventsExecutor`` (C++ event queue)
            instead of the ``SingleThreadedExecutor``, whose wait-set rebuild per callback
            makes a trial of some 1,500 callbacks per tick about 20 times slower
            (docs/benchmarks.md).
        time_factor: The simulator's clock at most this many times real time (0: as fast as
            the team answers; 1: as in the dome). Nodes in other processes that follow sim
            time (an external supervisor's heartbeat, against the 0.5 s sim-time deadman)
            need it.
        fault: Called as ``fault(nodes, executor)`` between spins (the fault matrix,
            tests/test_faults.py): it may remove and destroy a node (a crash) and add a new
            one to both (its restart).

    Raises:
        TimeoutError: When the trial does not finish within ``spec.timeout`` seconds.
        ValueError: Without blade drivers, or with ``processes`` / ``record``.
    """
    if not spec.blade_driver:
        raise ValueError("drive: continuous runs with blade drivers (the blade's tick interface)")
    if spec.record:
        raise ValueError("record: not with --drive continuous")
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter

    from ant_controller.controller_node import ControllerNode
    from blade_driver.driver_node import BladeDriverNode
    from blueprint_server.server_node import BlueprintServer
    from drive_executor.executor_node import ExecutorNode
    from excavation_bringup.team_tick import Phase
    from excavation_bringup.team_tick_node import TeamTickNode
    from excavation_bringup.trial import _supervisor_params
    from excavation_sim.dynamics import DynamicsParams
    from excavation_sim.dynamics_node import DynamicsNode
    from team_supervisor.supervisor_node import SupervisorNode

    full = spec.perception == "full"
    sim_time = Parameter("use_sim_time", value=True)
    physics = DynamicsParams.exact() if exact else DynamicsParams()
    context = Context()
    rclpy.init(context=context, domain_id=spec.domain)
    if events_executor:
        from rclpy.experimental.events_executor import EventsExecutor

        executor = EventsExecutor(context=context)
    else:
        executor = SingleThreadedExecutor(context=context)
    nodes = []
    started = time.monotonic()
    try:
        nodes.append(
            BlueprintServer(
                context=context,
                parameter_overrides=[Parameter("blueprint", value=spec.blueprint), sim_time],
            )
        )
        dynamics = DynamicsNode(
            context=context,
            parameter_overrides=[
                Parameter("blueprint", value=spec.blueprint),
                Parameter("robots", value=spec.robots),
                Parameter("seed", value=spec.seed),
                Parameter("scenario", value=spec.scenario),
                Parameter("noise_seed", value=spec.seed),
                Parameter("pose_prefix", value=TRUTH_PREFIX if full else ""),
                Parameter("snapshot_prefix", value=SNAPSHOT_PREFIX if full else ""),
                Parameter("idle_time_factor", value=IDLE_TIME_FACTOR),
                Parameter("time_factor", value=float(time_factor)),
            ]
            + [Parameter(name, value=value) for name, value in vars(physics).items()],
        )
        nodes.append(dynamics)
        blueprint = dynamics.blueprint
        if full:
            from excavation_bringup.perception import perception_nodes

            perception = perception_nodes(
                context,
                spec.robots,
                spec.seed,
                blueprint,
                spec.occlude,
                truth_prefix=SNAPSHOT_PREFIX,
            )
            for node in perception:
                node.set_parameters([sim_time])
            nodes += perception
        tick = TeamTickNode(
            context=context,
            parameter_overrides=[
                Parameter("robots", value=spec.robots),
                Parameter("steps", value=spec.steps),
                Parameter("seed", value=spec.seed),
                Parameter("scenario", value=spec.scenario),
                Parameter("blueprint", value=spec.blueprint),
                Parameter("word_timeout", value=float(spec.command_timeout)),
                sim_time,
            ],
        )
        nodes.append(tick)
        if spec.supervisor == "internal":
            nodes.append(
                SupervisorNode(
                    context=context,
                    parameter_overrides=[
                        Parameter(k, value=v)
                        for k, v in _supervisor_params(spec.robots, armed=True).items()
                    ]
                    + [sim_time],
                )
            )
        executors = []
        for k in range(spec.robots):
            ns = f"/robot_{k}"
            nodes.append(
                ControllerNode(
                    ctl,
                    context=context,
                    namespace=ns,
                    cli_args=controller_remaps(k, spec.robots),
                    parameter_overrides=[
                        Parameter("robot_id", value=k),
                        Parameter("robots", value=spec.robots),
                        Parameter("height_unit", value=blueprint.height_unit),
                        Parameter("lockstep", value=True),
                        Parameter("tilt_source", value="imu"),
                        sim_time,
                    ],
                )
            )
            nodes.append(
                BladeDriverNode(
                    context=context,
                    namespace=ns,
                    parameter_overrides=[Parameter("blade_after_motion", value=True), sim_time],
                )
            )
            drive = ExecutorNode(
                context=context,
                namespace=ns,
                parameter_overrides=[
                    Parameter("cell_size", value=float(blueprint.cell_size)),
                    Parameter("pose_topic", value=f"{TRUTH_PREFIX}{ns}/pose" if full else "pose"),
                    Parameter("seed", value=spec.seed * 1000 + k),
                    sim_time,
                ],
            )
            drive.trigger_configure()
            drive.trigger_activate()
            executors.append(drive)
            nodes.append(drive)
        for node in nodes:
            executor.add_node(node)
        while tick.core.phase is not Phase.FINISHED:
            if time.monotonic() - started > spec.timeout:
                raise TimeoutError(
                    f"trial did not finish within {spec.timeout} s (tick {tick.core.tick}, "
                    f"{tick.core.phase.value})"
                )
            executor.spin_once(timeout_sec=0.05)
            if fault is not None:
                fault(nodes, executor)
        world = dynamics.sim.world
        records = tick.core.records
        return TrialResult(
            world.fitness(),
            [dynamics.snapshots.get(f"tick {t}", float("nan")) for t in range(spec.steps + 1)],
            world.heights.copy(),
            {k: tick.core.missed[k] for k in range(spec.robots)},
            time.monotonic() - started,
            [r.words for r in records],
            tick_wall=[
                (later.started_wall if later else r.ended_wall) - r.started_wall
                for r, later in zip(records, [*records[1:], None], strict=True)
            ],
            primitives_aborted=sum(e.core.counters.primitives_aborted for e in executors),
            stuck_events=sum(sum(r.stuck) for r in records),
            sim_seconds=dynamics.now_ns * 1e-9,
            robots_late=sum(tick.core.late),
        )
    finally:
        for node in nodes:
            executor.remove_node(node)
            node.destroy_node()
        executor.shutdown()
        rclpy.try_shutdown(context=context)
