"""``ant-trial --drive continuous --processes``: the continuous trial, every node a process.

The nodes and parameters of :func:`excavation_bringup.continuous_trial.run_continuous`,
each started as its own process of this interpreter (what separate ``ros2 run`` commands
would start), by :class:`excavation_bringup.trial.TrialProcesses`: the bag recorder first
(``record``), the team supervisor (armed), the blueprint server, ``dynamics`` (the clock;
it rewrites ``world.json`` at every snapshot), with ``perception="full"`` the sensors,
localizer and mapper, per robot a controller (lockstep, remapped onto the team tick's
``/tick`` topics), a blade driver (sim backend) and a drive executor (a lifecycle node: its
program configures and activates it at start, as the composed trial does), both with the
deadman of :data:`SIM_DEADMAN`, and last the
team tick, whose exit after the last tick ends the trial (it writes ``result.json``).
Every node but ``dynamics`` runs on ``use_sim_time``.

The result is the composed trial's: fitness, fitness per tick and heights from
``world.json``; words, wall time per tick, stuck events and missed words from the team
tick's ``result.json``; the primitives the executors aborted from their last
``/diagnostics`` report (``primitives_aborted``), which a small node of this process reads.
"""

from __future__ import annotations

import json
import re
import tempfile
import time
from pathlib import Path

from excavation_bringup.continuous_trial import (
    SNAPSHOT_PREFIX,
    continuous_result,
    controller_parameters,
    controller_remaps,
    dynamics_parameters,
    executor_parameters,
    supervisor_parameters,
    tick_parameters,
)
from excavation_bringup.trial import (
    TrialProcesses,
    TrialResult,
    TrialSpec,
    _controller_args,
    node_command,
    recorder_command,
)

FINAL = "team_tick"
"""The node whose exit ends the trial."""
WORLD_FILE = "world.json"
COUNTERS_WAIT = 30.0
"""Wall seconds to wait, after the last tick, for every executor's next diagnostics report
(one per wall second)."""
DYNAMICS_COMMAND_TIMEOUT = 60.0
"""Wall seconds a ``dynamics`` step waits for every executor's ``cmd_vel`` (the most the
parameter allows): between processes on a loaded machine an answer can take longer than the
composed trial's 0.5 s, and a step taken without it would integrate the previous command."""
MAX_TIME_FACTOR = 20.0
"""``dynamics`` runs at most 20 times real time when the nodes are processes (composed: no
cap; it reaches some 40 x). Every node judges heartbeats and waits on the simulator's
clock, so a process held up for some wall time misses that many times more sim time: the
cap bounds it."""
SIM_DEADMAN = 10.0
"""Seconds of sim time without a team heartbeat that stop an executor or home a blade, in
a simulation whose nodes are processes (the field's limit is 0.5 s): with the clock at most
:data:`MAX_TIME_FACTOR` times real time, at least the field's 0.5 s of wall time. With the
field's 0.5 s of sim time, 25 ms of wall time at 20 x, a supervisor process held up by a
loaded machine tripped it (seen: "heartbeat lost (0.55 s old)" aborted both robots'
moves). Composed, every node shares one executor and one clock, and the field's value
holds."""
SIM_BLADE_WAIT = 60.0
"""Seconds of sim time the team tick waits for every blade to reach its setting before it
takes a snapshot anyway, when the nodes are processes (the composed trial: 2 s). The
blade's way from controller to blade driver to simulator and back is a few messages
between processes; the simulator's clock runs 10 x real time while the team stands
still, so 2 s of sim time is 0.2 s of wall time, which a loaded machine exceeds (seen: the
4-robot trial's words diverged from the grid's), and a snapshot with a blade not yet at
its setting changes what the controllers decide next. A fallback only: a blade that
arrives ends the wait."""
SIM_SNAPSHOT_RETRY = 20.0
"""Wall seconds the team tick waits for a snapshot's poses, height map and blades before it
asks the simulator for another instant, when the nodes are processes (composed: 2 s). A
request the simulator has not acknowledged is sent again unchanged, which renders nothing
twice (the simulator takes a request once); but a snapshot taken and still incomplete asks
for a new instant, a new camera frame and laser sweep: that moves the sensors' noise
stream on by a frame and gives the mapper a sweep the composed trial never fuses, so
asking only because the localizer and mapper processes are slow on a loaded machine
(seen: ``ant-dome up --sim`` asked again at ticks 0 and 20 of 40 on an idle 2-core
machine, with 2 s) makes the run differ from the composed one. A fallback only, for a
snapshot that lacks a robot (hidden from the camera) or was lost after it was taken."""
EXECUTOR_STATUS = re.compile(r"/robot_(\d+)/executor")


def continuous_commands(spec: TrialSpec, workdir: Path, exact: bool) -> dict[str, list[str]]:
    """Each node's command line for the continuous trial ``spec``, in start order.

    With ``perception="full"`` the camera calibration is written to ``workdir/camera.yaml``
    now; ``dynamics`` writes ``workdir/world.json``, the team tick ``workdir/result.json``.
    """
    from blueprint_server.blueprint import resolve_blueprint

    bp = resolve_blueprint(spec.blueprint)
    workdir = Path(workdir)
    sim = {"use_sim_time": True}
    commands: dict[str, list[str]] = {}
    if spec.record:
        commands["recorder"] = recorder_command(spec, bp.height_unit)
    commands["supervisor"] = node_command(
        "supervisor", "team_supervisor.supervisor_node", **supervisor_parameters(spec), **sim
    )
    commands["server"] = node_command(
        "server", "blueprint_server.server_node", blueprint=spec.blueprint, **sim
    )
    commands["dynamics"] = node_command(
        "dynamics",
        "excavation_sim.dynamics_node",
        **dynamics_parameters(spec, exact),
        command_timeout=min(float(spec.command_timeout), DYNAMICS_COMMAND_TIMEOUT),
        max_time_factor=MAX_TIME_FACTOR,
        result_file=str(workdir / WORLD_FILE),
    )
    if spec.perception == "full":
        from excavation_bringup.perception import perception_parameters

        values = perception_parameters(
            spec.robots, spec.seed, bp, str(workdir / "camera.yaml"), spec.occlude, processes=True
        )
        values["sensors"]["truth_prefix"] = SNAPSHOT_PREFIX
        for name, module in (
            ("sensors", "excavation_sim.sensors_node"),
            ("localizer", "overhead_localizer.localizer_node"),
            ("mapper", "terrain_mapper.mapper_node"),
        ):
            commands[name] = node_command(name, module, **values[name], **sim)
    for k in range(spec.robots):
        ns = f"/robot_{k}"
        commands[f"controller_{k}"] = node_command(
            "controller",
            "ant_controller.controller_node",
            *_controller_args(spec.controller),
            ns=ns,
            remaps=controller_remaps(k, spec.robots)[2::2],  # past "--ros-args", each "-r"
            **controller_parameters(spec, k, bp.height_unit),
            **sim,
        )
        commands[f"blade_driver_{k}"] = node_command(
            "blade_driver",
            "blade_driver.driver_node",
            ns=ns,
            backend="sim",
            blade_after_motion=True,
            deadman=SIM_DEADMAN,
            **sim,
        )
        commands[f"executor_{k}"] = node_command(
            "executor",
            "drive_executor.executor_node",
            ns=ns,
            **executor_parameters(spec, k, bp.cell_size),
            deadman=SIM_DEADMAN,
            **sim,
        )
    commands[FINAL] = node_command(
        FINAL,
        "team_tick.node",
        **tick_parameters(spec),
        blade_wait=SIM_BLADE_WAIT,
        snapshot_retry=SIM_SNAPSHOT_RETRY,
        result_file=str(workdir / "result.json"),
        **sim,
    )
    return commands


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


def run_continuous_processes(spec: TrialSpec, exact: bool = False) -> TrialResult:
    """Run the continuous trial of ``spec`` with every node in its own process.

    Raises:
        TimeoutError: Not finished within ``spec.timeout`` seconds.
        RuntimeError: A node failed, or a result is missing (naming the node and its log).
    """
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor

    from excavation_bringup.continuous_trial import check_spec

    check_spec(spec)
    started = time.monotonic()
    counters = ExecutorCounters(spec.robots)
    context = Context()
    from excavation_common.ros import init_rclpy

    init_rclpy(context=context, domain_id=spec.domain)
    node = rclpy.create_node("ant_trial", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    node.create_subscription(DiagnosticArray, "/diagnostics", counters.on_diagnostics, 50)
    try:
        with tempfile.TemporaryDirectory(prefix="ant-trial-") as tmp:
            workdir = Path(tmp)
            commands = continuous_commands(spec, workdir, exact)
            with TrialProcesses(spec, workdir, commands=commands, final=FINAL) as trial:
                trial.start()
                ticks = trial.wait(
                    spec.timeout, started, idle=lambda: executor.spin_once(timeout_sec=0.1)
                )
                ended = time.monotonic()
                deadline = ended + COUNTERS_WAIT
                while counters.missing_since(ended) and time.monotonic() < deadline:
                    trial.check()
                    executor.spin_once(timeout_sec=0.1)
                silent = counters.missing_since(ended)
                if silent:
                    raise RuntimeError(
                        f"executors of robots {silent} did not report on /diagnostics "
                        f"within {COUNTERS_WAIT:.0f} s of the last tick"
                    )
                world = json.loads((workdir / WORLD_FILE).read_text())
                if f"tick {spec.steps}" not in world["snapshots"]:
                    raise RuntimeError(f"dynamics wrote no snapshot of tick {spec.steps}")
                seconds = time.monotonic() - started
    finally:
        executor.remove_node(node)
        node.destroy_node()
        executor.shutdown()
        rclpy.try_shutdown(context=context)
    return continuous_result(ticks, world, sum(counters.aborted.values()), seconds, spec.steps)
