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

import numpy as np

from excavation_bringup.trial import TrialResult, TrialSpec, close_composed

TICK_PREFIX = "/tick"
SNAPSHOT_PREFIX = "/snapshot"
TRUTH_PREFIX = "/truth"
IDLE_TIME_FACTOR = 10.0
"""The simulator's clock runs at most 10 x real time while the team stands still (the
controllers decide, a snapshot is rendered): otherwise it races through those waits,
spending the CPU they need."""


RECORD_TAIL = 1.0
"""Wall seconds a recording trial runs on after its last tick, so that the bag holds the
messages still in flight (the last snapshot, statuses and diagnostics)."""


class RecorderThread:
    """The bag recorder on its own single-threaded executor, spun by a thread.

    The ``EventsExecutor`` of the trial cannot take the recorder's raw (CDR bytes)
    messages (``SystemError: null argument to internal routine``), so the recorder runs
    beside it, as a second component container would.
    """

    def __init__(self, node, context) -> None:
        import threading

        from rclpy.executors import SingleThreadedExecutor

        self.node = node
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(node)
        self.running = True
        self.thread = threading.Thread(target=self._spin, name="bag-recorder", daemon=True)
        self.thread.start()

    def _spin(self) -> None:
        while self.running:
            self.executor.spin_once(timeout_sec=0.05)

    def close(self) -> None:
        """Stop spinning, finish the bag and destroy the node."""
        self.running = False
        self.thread.join()
        self.node.close()
        self.executor.remove_node(self.node)
        self.node.destroy_node()
        self.executor.shutdown()


def check_spec(spec: TrialSpec) -> None:
    """Refuse what a continuous trial cannot run.

    Raises:
        ValueError: Without blade drivers (the blade's tick interface).
    """
    if not spec.blade_driver:
        raise ValueError("drive: continuous runs with blade drivers (the blade's tick interface)")


def controller_remaps(robot: int, robots: int) -> list[str]:
    """``cli_args`` that point a lockstep controller at the team tick's snapshot topics."""
    args = ["--ros-args"]
    for j in range(robots):
        args += ["-r", f"/robot_{j}/pose:={TICK_PREFIX}/robot_{j}/pose"]
    args += ["-r", f"/worksite/height_map:={TICK_PREFIX}/worksite/height_map"]
    args += ["-r", f"/robot_{robot}/stuck:={TICK_PREFIX}/robot_{robot}/stuck"]
    return args


def dynamics_parameters(spec: TrialSpec, exact: bool) -> dict:
    """The ``dynamics`` node's parameters for ``spec`` (both trial modes)."""
    from excavation_sim.dynamics import DynamicsParams

    full = spec.perception == "full"
    physics = DynamicsParams.exact() if exact else DynamicsParams()
    return {
        "blueprint": spec.blueprint,
        "robots": spec.robots,
        "seed": spec.seed,
        "scenario": spec.scenario,
        "noise_seed": spec.seed,
        "pose_prefix": TRUTH_PREFIX if full else "",
        "snapshot_prefix": SNAPSHOT_PREFIX if full else "",
        "idle_time_factor": IDLE_TIME_FACTOR,
    } | vars(physics)


def tick_parameters(spec: TrialSpec) -> dict:
    """The team tick's parameters for ``spec``."""
    return {
        "robots": spec.robots,
        "steps": spec.steps,
        "seed": spec.seed,
        "scenario": spec.scenario,
        "blueprint": spec.blueprint,
        "word_timeout": float(spec.command_timeout),
        "wait_for_ready": True,  # tick 0 waits for every controller's inputs to be connected
        "wait_for_recorder": bool(spec.record),  # and for the recorder, so the bag has tick 0
    }


def supervisor_parameters(spec: TrialSpec) -> dict:
    """The team supervisor's parameters (armed at start)."""
    from excavation_bringup.trial import _supervisor_params

    # The lost-robot policy on (missed frames, busy executors: team_supervisor.team).
    return _supervisor_params(spec.robots, armed=True)


def controller_parameters(spec: TrialSpec, k: int, height_unit: float) -> dict:
    """Robot ``k``'s controller (lockstep, on the team tick's topics: controller_remaps)."""
    return {
        "robot_id": k,
        "robots": spec.robots,
        "height_unit": float(height_unit),
        "lockstep": True,
        "tilt_source": "imu",
    }


def executor_parameters(spec: TrialSpec, k: int, cell_size: float) -> dict:
    """Robot ``k``'s drive executor (in namespace ``/robot_k``)."""
    pose = f"{TRUTH_PREFIX}/robot_{k}/pose" if spec.perception == "full" else "pose"
    return {"cell_size": float(cell_size), "pose_topic": pose, "seed": spec.seed * 1000 + k}


def continuous_result(
    ticks: dict, world: dict, primitives_aborted: int, seconds: float, steps: int
) -> TrialResult:
    """The trial's result from the team tick's summary and the ``dynamics`` world.

    Args:
        ticks: :meth:`team_tick.core.TeamTick.summary`.
        world: :meth:`excavation_sim.dynamics_node.DynamicsNode.result`.
        primitives_aborted: Summed over the executors.
        seconds: Wall time of the trial.
        steps: Ticks run (the fitness trace has one more entry).
    """
    return TrialResult(
        world["fitness"],
        [world["snapshots"].get(f"tick {t}", float("nan")) for t in range(steps + 1)],
        np.array(world["heights"], dtype=np.int64),
        {int(k): n for k, n in ticks["missed"].items()},
        seconds,
        ticks["commands"],
        holds=ticks.get("holds", 0),
        tick_wall=ticks["tick_wall"],
        primitives_aborted=primitives_aborted,
        stuck_events=ticks["stuck_events"],
        sim_seconds=world["sim_seconds"],
        robots_late=ticks["robots_late"],
    )


def run_continuous(
    ctl,
    spec: TrialSpec,
    exact: bool = False,
    events_executor: bool = True,
    time_factor: float = 0.0,
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

    Raises:
        TimeoutError: When the trial does not finish within ``spec.timeout`` seconds.
        ValueError: Without blade drivers.
    """
    check_spec(spec)
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter
    from team_tick.core import Phase
    from team_tick.node import TeamTickNode

    from ant_controller.controller_node import ControllerNode
    from blade_driver.driver_node import BladeDriverNode
    from blueprint_server.server_node import BlueprintServer
    from drive_executor.executor_node import ExecutorNode
    from excavation_bringup.trial import trial_recorder
    from excavation_sim.dynamics_node import DynamicsNode
    from team_supervisor.supervisor_node import SupervisorNode

    full = spec.perception == "full"
    sim_time = Parameter("use_sim_time", value=True)

    def overrides(values: dict) -> list:
        return [Parameter(k, value=v) for k, v in values.items()] + [sim_time]

    context = Context()
    from excavation_common.ros import init_rclpy

    init_rclpy(context=context, domain_id=spec.domain)
    if events_executor:
        from rclpy.experimental.events_executor import EventsExecutor

        executor = EventsExecutor(context=context)
    else:
        executor = SingleThreadedExecutor(context=context)
    nodes = []
    recorder = None
    started = time.monotonic()
    try:
        if spec.record:  # first, so that it sees every topic appear
            recorder = RecorderThread(trial_recorder(context, spec), context)
        nodes.append(
            BlueprintServer(
                context=context,
                parameter_overrides=[Parameter("blueprint", value=spec.blueprint), sim_time],
            )
        )
        dynamics = DynamicsNode(
            context=context,
            parameter_overrides=[
                Parameter(k, value=v)
                for k, v in (
                    dynamics_parameters(spec, exact) | {"time_factor": float(time_factor)}
                ).items()
            ],
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
        tick = TeamTickNode(context=context, parameter_overrides=overrides(tick_parameters(spec)))
        nodes.append(tick)
        if spec.supervisor == "internal":
            nodes.append(
                SupervisorNode(
                    context=context, parameter_overrides=overrides(supervisor_parameters(spec))
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
                    parameter_overrides=overrides(
                        controller_parameters(spec, k, blueprint.height_unit)
                    ),
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
                parameter_overrides=overrides(executor_parameters(spec, k, blueprint.cell_size)),
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
        result = continuous_result(
            tick.core.summary(),
            dynamics.result(),
            sum(e.core.counters.primitives_aborted for e in executors),
            time.monotonic() - started,
            spec.steps,
        )
        if recorder is not None:  # what is still in flight
            last = time.monotonic() + RECORD_TAIL
            while time.monotonic() < last:
                executor.spin_once(timeout_sec=0.05)
        return result
    finally:
        close_composed(executor, nodes, context, recorder)
