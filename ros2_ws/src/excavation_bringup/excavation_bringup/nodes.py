"""One function per node kind: its node spec from a deployment and a timing profile.

A node spec is a node's name, namespace, parameters, remaps, clock and restart rule; each
function here makes one from a :class:`~excavation_bringup.deployment.Deployment` and a
:class:`~excavation_bringup.profiles.TimingProfile`.

These functions are the only place where a node's parameters are chosen for a trial or a
dome; the graph functions (:mod:`excavation_bringup.graph`) only pick which nodes run and in
what order, and the launchers (:mod:`excavation_bringup.launch`) only start them. A run from
a site file takes topics, offsets, the LED table and its ``overrides:`` from the site; a
trial from command-line options takes them from the blueprint. ``docs/architecture.md``
("Node kinds") lists the kinds; the parameters themselves are declared once, in each node's
parameter dataclass (the registry :mod:`excavation_bringup.kinds` names them).

Pure module: no ``rclpy``.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

from excavation_bringup import site as sitefile
from excavation_bringup.deployment import Deployment
from excavation_bringup.kinds import kind as node_kind
from excavation_bringup.node_params import NodeParams
from excavation_bringup.profiles import TimingProfile
from excavation_common.topics import DOME_BLADE_OUT, tick_remaps

SNAPSHOT_PREFIX = "/snapshot"
"""Where ``dynamics`` publishes the instant the team tick asked for (the sensors render it)."""
TRUTH_PREFIX = "/truth"
"""Where a simulator publishes its truth with full perception."""
WORLD_PREFIX = "/sim"
"""A rehearsal: where the simulated world's own topics go (its clock, the commands its
bases and boards take, the IMU readings, the blades' plant states), so that the dome's graph
holds only what the dome's drivers publish (the emulators read and write these)."""
WORLD_SNAPSHOT_PERIOD = 0.25
"""A rehearsal: sim seconds between the world's height maps (the emulated laser's truth)."""

LOST_TIMEOUT = 1.5
"""Seconds of pose stamps (1.5 ticks) after which a simulated trial's supervisor stops a
silent robot: more than one tick, since the poses of one tick arrive one after another."""
LOST_GRACE = 2.0
"""Further seconds (2 ticks) before a lost robot is disabled for the rest of the trial."""

TRIAL_SWEEP_SCANS = 32
"""Scans per laser sweep in a trial from command-line options: half the mapper's default,
since every message costs a composed trial's single executor a few milliseconds; one such
sweep still measures every cell not under a robot to 0.05 soil unit RMSE
(docs/perception.md)."""

RETAKES = 2
"""Frames of one instant the localiser may ask the synthetic camera for when a robot it was
tracking is not seen. One frame per tick means a robot hidden by one frame's glare (about 1
robot-frame in 2,000, docs/perception.md) would hold a lockstep team for a whole tick
timeout; a second frame of the same instant has its own glare."""

DOME_BLADE_IN = "blade/joint_states"
"""The dome: the team tick's measured blade is each blade driver's joint state."""
# DOME_BLADE_OUT (excavation_common.topics): the dome's blade state the team tick
# republishes per tick, the controller's (remapped): the serial driver's own joint state is
# stamped on the wall clock, never with a tick.

SIM_EXECUTOR: dict[str, Any] = {
    "cmd_vel_stamp": "pose",
    "future_tolerance": 10.0,
    "clock_offset_limit": 10.0,
}
"""A simulated executor keeps the continuous simulator's lockstep: ``dynamics`` steps once
every robot has sent a ``cmd_vel`` stamped with its step, so a command carries the stamp of
the pose it answers; and the executor's reading of ``/clock`` (a best-effort topic of its
own) can trail a step's pose by a step or more, which is no clock offset (one process
stamps both), so neither the future-pose rule nor its warning applies. With these values
every simulated trial runs exactly as before these parameters existed."""

DOME_EXECUTOR: dict[str, Any] = {
    "position_tolerance": 0.012,
    "min_progress": 0.012,
    "predict_pose": True,
}
"""The dome's executors close their loop on the localiser, whose median position error is
0.046 cell, 11.5 mm (docs/benchmarks.md, "Perception"): a drive ends within 12 mm of the
cell centre (not the simulator's 8 mm, where the pose noise is 2 mm) and must make 12 mm of
progress per ``progress_window`` (not 4 mm, which a stalled robot's pose noise alone can
show). When a pose is stale is the dome timing profile's ``pose_timeout``
(:data:`excavation_bringup.profiles.DOME`). Each pose is advanced by its age along the
twist last sent (``predict_pose``): acted on as it was, a drive overshot its cell by the
distance covered while the frame was processed.
Only here, so that no simulated trial changes; a site tunes them under ``overrides:
{executor: ...}``."""


@dataclass(frozen=True)
class NodeSpec:
    """One node of a graph.

    Attributes:
        name: Unique label (log file, state, reports), e.g. ``controller_1``.
        kind: Its node kind (:data:`excavation_bringup.kinds.KINDS`).
        params: Its parameters, typed (:class:`~excavation_bringup.node_params.NodeParams`;
            a process gets them as ``RUN/params/NAME.yaml``, :meth:`ros_params`).
        diagnostics: ``/diagnostics`` status names (or prefixes ending in ``*``) that show
            the node is up.
        args: Command-line arguments before ``--ros-args``.
        namespace: ROS namespace (``/robot_k``), or empty.
        restart: The dome restarts it when it crashes.
        final: Its exit with code 0 ends the run (the team tick after its ticks).
        remaps: Topic remappings ``from:=to``.
        module: ``python -m`` module, when not the kind's (the recorder runs through
            ``ant-bag record``).
        host: The site's host that runs it (``ant-dome up --host``); empty: the dome PC.
        sim_time: It runs on the simulator's ``/clock`` (``use_sim_time``); the graph sets
            it (:func:`excavation_bringup.graph.continuous`).
    """

    name: str
    kind: str
    params: NodeParams
    diagnostics: tuple[str, ...]
    args: tuple[str, ...] = ()
    namespace: str = ""
    restart: bool = True
    final: bool = False
    remaps: tuple[str, ...] = ()
    module: str = ""
    host: str = ""
    sim_time: bool = False

    def ros_params(self) -> dict[str, Any]:
        """What its parameter file holds: the given parameters, and ``use_sim_time``."""
        return self.params.ros() | ({"use_sim_time": True} if self.sim_time else {})

    def command(self, params_file: str | Path) -> list[str]:
        """The command line that starts it (this interpreter, as ``ros2 run`` would)."""
        module = self.module or node_kind(self.kind).module
        cmd = [sys.executable, "-m", module, *self.args, "--ros-args"]
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


@dataclass(frozen=True)
class RunFiles:
    """The files of one run, all in its run directory.

    Attributes:
        run_dir: The run directory (logs, parameters, results).
        calibration: The camera model the localiser loads (a site's own file, or the
            synthetic camera's, written here by the graph).
    """

    run_dir: Path
    calibration: str = ""

    @property
    def beacons(self) -> Path:
        """The site's LED table, as the localiser reads it."""
        return self.run_dir / "beacons.yaml"

    @property
    def world(self) -> Path:
        """``dynamics``: the world at every snapshot (fitness, heights)."""
        return self.run_dir / "world.json"

    @property
    def result(self) -> Path:
        """The final node's summary after its last tick (``sim`` or the team tick)."""
        return self.run_dir / "result.json"

    def board_link(self, k: int) -> Path:
        """A rehearsal: the port name of robot ``k``'s emulated servo board (a symlink)."""
        return self.run_dir / f"robot_{k}_blade"


class Geometry:
    """Grid, laser and soil unit of a deployment: the site's, or its blueprint's."""

    def __init__(self, dep: Deployment) -> None:
        self.dep = dep

    @cached_property
    def blueprint(self):
        """The resolved blueprint."""
        from blueprint_server.blueprint import resolve_blueprint

        return resolve_blueprint(self.dep.blueprint)

    @cached_property
    def laser(self):
        """The synthetic laser's parameters over a trial's site (no site file)."""
        from excavation_sim.laser import LaserParams

        rows, cols = self.blueprint.shape
        return LaserParams.for_site(
            rows, cols, float(self.blueprint.cell_size), sweep_scans=TRIAL_SWEEP_SCANS
        )

    @property
    def rows(self) -> int:
        """Grid rows."""
        site = self.dep.site
        return site.worksite.rows if site is not None else int(self.blueprint.shape[0])

    @property
    def cols(self) -> int:
        """Grid columns."""
        site = self.dep.site
        return site.worksite.cols if site is not None else int(self.blueprint.shape[1])

    @property
    def cell_size(self) -> float:
        """Cell edge, m."""
        site = self.dep.site
        return float(site.worksite.cell_size if site is not None else self.blueprint.cell_size)

    @property
    def height_unit(self) -> float:
        """One soil unit, m."""
        site = self.dep.site
        return float(site.worksite.soil_unit if site is not None else self.blueprint.height_unit)

    @property
    def sweep_scans(self) -> int:
        """Scans per laser sweep."""
        site = self.dep.site
        return site.laser.sweep_scans if site is not None else self.laser.sweep_scans


# --- helpers ---------------------------------------------------------------------------------


def _continuous_sim(dep: Deployment) -> bool:
    """The continuous-motion simulator is the clock of every other node."""
    return dep.drive == "continuous" and dep.sim


def _params(
    dep: Deployment,
    kind: str,
    name: str,
    derived: dict[str, Any],
    tuned: dict[str, Any] | None = None,
    robot: int | None = None,
) -> NodeParams:
    """Node ``name``'s parameters: ``derived`` and ``tuned`` with the site's ``overrides:``.

    ``derived`` is what the run fixes (from the site or the options: no override may change
    it), with what the site's node-parameter fields set (robot ``robot``'s, for a per-robot
    node: :func:`excavation_bringup.site.node_values`); ``tuned`` the mode's or profile's
    choices (a site may override them);
    :class:`~excavation_bringup.node_params.NodeParams` checks every value.
    """
    site = dep.site
    if site is None:
        return NodeParams.build(kind, name, derived, tuned)
    fields = sitefile.node_values(site, kind, robot)
    tuned = {n: v for n, v in (tuned or {}).items() if n not in fields}
    overrides = site.overrides.get(kind, {})
    return NodeParams.build(kind, name, derived | fields, tuned, overrides, site.path)


def _sim_deadman(dep: Deployment, profile: TimingProfile) -> dict[str, Any]:
    """The deadman of a node on the simulator's clock (the profile's), else the node's own."""
    if profile.deadman is not None and _continuous_sim(dep):
        return {"deadman": profile.deadman}
    return {}


def robot_namespace(k: int) -> str:
    """Robot ``k``'s namespace (robots are named by their index)."""
    return f"/robot_{k}"


# --- the node kinds -------------------------------------------------------------------------


def site_topics(site: sitefile.Site) -> list[str]:
    """What a site's recorder records: the suite's topics and the site's own topics.

    A dome's drivers publish where the site says: its camera, laser, mount and bases.
    """
    from excavation_bags.topics import SUITE_TOPICS

    named = [site.camera.image_topic, site.camera.camera_info_topic, site.laser.scan_topic]
    named += [site.laser.mount_state_topic, *(robot.drive_topic for robot in site.robots)]
    topics = list(SUITE_TOPICS)
    for topic in named:
        if topic and topic not in topics:
            topics.append(topic)
    return topics


def recorder(dep: Deployment, geometry: Geometry) -> NodeSpec:
    """The bag recorder (``ant-bag record``), first, so that it sees every topic appear.

    From a site it records the site's topics too (:func:`site_topics`). Not restartable: a
    second recorder cannot reopen the bag.
    """
    derived: dict[str, Any] = {"out": str(dep.record), "height_unit": geometry.height_unit}
    tuned = {"topics": site_topics(dep.site)} if dep.site is not None else {}
    return NodeSpec(
        "recorder",
        "recorder",
        _params(dep, "recorder", "recorder", derived, tuned),
        ("/bag_recorder",),
        args=("record", "--out", str(dep.record)),
        restart=False,
        module="excavation_bags.cli",
    )


def supervisor(dep: Deployment) -> NodeSpec:
    """The team supervisor: armed at start when simulated, disarmed in the dome.

    In the dome nothing moves until the operator runs ``ant-operator arm``. A simulated run
    is unattended, so its supervisor arms the team itself, with the lost-robot policy's
    trial timing (:data:`LOST_TIMEOUT`, :data:`LOST_GRACE`); a lockstep trial watches poses
    only with full perception, where the localiser can lose a robot (with truth the
    simulator publishes a tick's poses together, and a busy supervisor could only misjudge
    a robot from their order).
    """
    derived: dict[str, Any] = {"robots": dep.robots, "arm_at_start": dep.sim}
    tuned: dict[str, Any] = {}
    if dep.sim:
        tuned |= {"lost_timeout": LOST_TIMEOUT, "lost_grace": LOST_GRACE}
    if dep.drive == "grid":
        tuned["watch_poses"] = dep.full
    params = _params(dep, "supervisor", "supervisor", derived, tuned)
    return NodeSpec("supervisor", "supervisor", params, ("/supervisor",))


def server(dep: Deployment) -> NodeSpec:
    """The blueprint server (it alone publishes ``/worksite/map_info``)."""
    return NodeSpec(
        "server",
        "server",
        _params(dep, "server", "server", {"blueprint": dep.blueprint}),
        ("/blueprint_server", "blueprint_server: *"),
    )


def sim(dep: Deployment, files: RunFiles, processes: bool) -> NodeSpec:
    """The lockstep simulator: the clock of a grid trial, and its final node.

    Tick 0 waits for every controller's ``ready`` (each has connected all its inputs, the
    blade driver's joint states among them); with full perception its truth moves under
    ``/truth``; as a process it writes ``result.json`` at the end and, with a recorder, tick
    0 waits for it.
    """
    params: dict[str, Any] = {
        "blueprint": dep.blueprint,
        "robots": dep.robots,
        "steps": dep.steps,
        "seed": dep.seed,
        "scenario": dep.scenario,
        "command_timeout": float(dep.command_timeout),
        "blade_driver": dep.blade_driver,
        "wait_for_ready": True,
    }
    if processes:
        params |= {"result_file": str(files.result), "wait_for_recorder": bool(dep.record)}
    if dep.full:
        params["truth_prefix"] = TRUTH_PREFIX
    return NodeSpec(
        "sim", "sim", _params(dep, "sim", "sim", params), ("/sim",), restart=False, final=True
    )


def dynamics(dep: Deployment, profile: TimingProfile, files: RunFiles) -> NodeSpec:
    """The continuous-motion simulator: the clock of every other node.

    With full perception its per-step truth goes under ``/truth`` (the executors' loop)
    and the snapshots the team tick asks for under ``/snapshot`` (what the synthetic
    camera and laser render). It writes ``world.json`` at every snapshot. Not restartable:
    a new one would start the world over.
    """
    derived, tuned = _dynamics_values(dep, profile, files)
    params = _params(dep, "dynamics", "dynamics", derived, tuned)
    return NodeSpec("dynamics", "dynamics", params, ("/dynamics",), restart=False)


def _dynamics_values(
    dep: Deployment, profile: TimingProfile, files: RunFiles
) -> tuple[dict[str, Any], dict[str, Any]]:
    """``dynamics``' derived and tuned values (its physics and timing are tuned)."""
    from excavation_sim.dynamics import DynamicsParams

    physics = DynamicsParams.exact() if dep.exact else DynamicsParams()
    derived: dict[str, Any] = {
        "blueprint": dep.blueprint,
        "robots": dep.robots,
        "seed": dep.seed,
        "scenario": dep.scenario,
        "noise_seed": dep.seed,
        "pose_prefix": TRUTH_PREFIX if dep.full else "",
        "snapshot_prefix": SNAPSHOT_PREFIX if dep.full else "",
        "soil": dep.soil,
        # the synthetic laser of full perception sees the physical soil's fine field
        "fine_height_map": dep.full and dep.soil != "grid" and dep.sim,
        "time_factor": float(dep.time_factor),
        "result_file": str(files.world),
    }
    tuned: dict[str, Any] = {"idle_time_factor": profile.idle_time_factor} | vars(physics)
    if profile.dynamics_command_timeout is not None:
        tuned["command_timeout"] = min(float(dep.command_timeout), profile.dynamics_command_timeout)
    if profile.max_time_factor is not None:
        tuned["max_time_factor"] = profile.max_time_factor
    return derived, tuned


def sensors(dep: Deployment, geometry: Geometry) -> NodeSpec:
    """The synthetic overhead camera and laser, rendering the simulator's truth.

    A lockstep trial renders ``/truth`` every tick, a continuous one the snapshot
    ``dynamics`` took for the team tick (``/snapshot``).
    """
    derived: dict[str, Any] = {
        "robots": dep.robots,
        "seed": dep.seed,
        "truth_prefix": SNAPSHOT_PREFIX if dep.drive == "continuous" else TRUTH_PREFIX,
        "sweep_scans": geometry.sweep_scans,
        "cell_size": geometry.cell_size,
        "rows": geometry.rows,
        "cols": geometry.cols,
    }
    if dep.occlude:
        derived["occlude"] = dep.occlude
    params = _params(dep, "sensors", "sensors", derived, {"reliable": True})
    return NodeSpec("sensors", "sensors", params, ("/sensors",))


def localizer(dep: Deployment, files: RunFiles, view: bool = False) -> NodeSpec:
    """The overhead localiser: camera topics, calibration and (a site's) LED table.

    Simulated, the synthetic camera is reliable, renders one frame per tick and answers
    retakes (:data:`RETAKES`). With the live view it publishes annotated frames.
    """
    derived: dict[str, Any] = {"robots": dep.robots, "calibration": files.calibration}
    site = dep.site
    if site is not None:
        c = site.camera
        derived |= {
            "beacons": str(files.beacons),
            "image_topic": c.image_topic,
            "compressed": c.compressed,
            "camera_info_topic": c.camera_info_topic,
        }
    tuned: dict[str, Any] = {"reliable": dep.sim, "retakes": RETAKES if dep.sim else 0}
    if view:
        tuned["annotated_period"] = 0.5
    return NodeSpec(
        "localizer",
        "localizer",
        _params(dep, "localizer", "localizer", derived, tuned),
        ("/localizer", "localizer: *"),
    )


def mapper(dep: Deployment, profile: TimingProfile, geometry: Geometry) -> NodeSpec:
    """The terrain mapper: grid, mount pose and offsets; never a ``map_info`` publisher.

    It starts from a level site (``prior_known``: the survey before the robots enter), so
    the cells under the robots' start positions have a value before any beam reaches them.
    The profile's waits are fallbacks: current poses end ``pose_wait`` at once, a mount
    state ``mount_wait``.
    """
    site = dep.site
    if site is not None:
        w, las = site.worksite, site.laser
        mount = las.mount
        laser = {
            "pan_offset": float(las.pan_offset),
            "tilt_offset": float(las.tilt_offset),
            "roll_offset": float(las.roll_offset),
            "sweep_scans": las.sweep_scans,
            "scan_topic": las.scan_topic,
            "mount_topic": las.mount_state_topic,
        }
        prior = {
            "prior_known": w.prior_height is not None,
            "prior_height": float(w.prior_height or 0.0),
        }
        robot_height = las.robot_height
    else:
        mount = geometry.laser.mount
        laser = {"sweep_scans": geometry.sweep_scans}
        prior = {"prior_known": True, "prior_height": 0.0}
        robot_height = geometry.laser.robot_height
    derived: dict[str, Any] = {
        "robots": dep.robots,
        "rows": geometry.rows,
        "cols": geometry.cols,
        "cell_size": geometry.cell_size,
        "mount_x": float(mount[0]),
        "mount_y": float(mount[1]),
        "mount_z": float(mount[2]),
        **laser,
        **prior,
        "robot_height": float(robot_height),
    }
    tuned = {
        "publish_map_info": False,
        "pose_wait": profile.pose_wait,
        "mount_wait": profile.mount_wait,
        "reliable": dep.sim,
    }
    return NodeSpec(
        "mapper",
        "mapper",
        _params(dep, "mapper", "mapper", derived, tuned),
        ("/mapper", "mapper"),
    )


def controller_remaps(dep: Deployment, k: int) -> tuple[str, ...]:
    """A continuous run's controller reads the team tick's snapshot (``/tick``).

    In the dome its blade state is the tick's too (:data:`DOME_BLADE_OUT`); simulated, the
    blade driver's ``sim`` backend already stamps it with the tick.
    """
    if dep.drive != "continuous":
        return ()
    return tuple(tick_remaps(range(dep.robots), k, dome_blade=not dep.sim))


def controller_args(spec: str) -> tuple[str, ...]:
    """The controller's command-line arguments for a genome file or ``"hand-coded"``."""
    return ("--hand-coded",) if spec == sitefile.HAND_CODED else ("--genome", spec)


def controller(dep: Deployment, k: int, geometry: Geometry) -> NodeSpec:
    """Robot ``k``'s controller (its genome on the command line), lockstep.

    In a continuous run it decides once per team tick on the tick's topics
    (:func:`controller_remaps`), and R1 comes from the robot's IMU (``tilt_source: imu``:
    the simulator's, or the robot's own where the site says it carries one, ``imu: true``);
    a site robot without one (``imu: false``) takes R1 from the height map.
    """
    ns = robot_namespace(k)
    derived: dict[str, Any] = {
        "robot_id": k,
        "robots": dep.robots,
        "height_unit": geometry.height_unit,
    }
    if dep.drive == "continuous":
        imu = dep.site is None or dep.site.robots[k].imu
        derived["tilt_source"] = "imu" if imu else "height_map"
    name = f"controller_{k}"
    return NodeSpec(
        name,
        "controller",
        _params(dep, "controller", name, derived, {"lockstep": True}, robot=k),
        (f"{ns}/controller",),
        args=controller_args(dep.robot_controller(k)),
        namespace=ns,
        remaps=controller_remaps(dep, k),
    )


def robot_host(dep: Deployment, k: int) -> str:
    """The host of robot ``k``'s own nodes: its executor and blade driver.

    A rehearsal's emulated base and servo board too (the robot's hardware). The site's
    ``robots[k].host``; empty for the dome PC (and without a site, and with ``--sim``).
    """
    if dep.site is None or dep.sim:
        return ""
    host = dep.site.robot_host(k)
    return "" if host == dep.site.dome_host else host


def blade_driver(dep: Deployment, k: int, profile: TimingProfile, files: RunFiles) -> NodeSpec:
    """Robot ``k``'s blade driver; simulated, the simulator is the board.

    In a rehearsal its port is the emulated board's (:meth:`RunFiles.board_link`), the one
    value of the dome's table a rehearsal changes.

    With drive executors a tick's blade bits wait for the end of its drive
    (``blade_after_motion``, Table 2 order); the lockstep simulator ends no drive, so there
    it stays off.
    """
    ns = robot_namespace(k)
    robot = dep.site.robots[k] if dep.site is not None else None
    backend = "sim" if dep.sim or robot is None else robot.backend
    derived: dict[str, Any] = {"backend": backend}
    tuned: dict[str, Any] = {}
    if dep.drive == "continuous":
        tuned["blade_after_motion"] = True
    if backend == "serial":
        derived["port"] = str(files.board_link(k)) if dep.emulated else robot.port
    tuned |= _sim_deadman(dep, profile)
    if robot_host(dep, k):
        derived["rearm_after_loss"] = True
    name = f"blade_driver_{k}"
    return NodeSpec(
        name,
        "blade_driver",
        _params(dep, "blade_driver", name, derived, tuned, robot=k),
        (f"{ns}/blade_driver",),
        namespace=ns,
        host=robot_host(dep, k),
    )


def executor(dep: Deployment, k: int, profile: TimingProfile, geometry: Geometry) -> NodeSpec:
    """Robot ``k``'s drive executor (a lifecycle node: its program configures and activates it).

    Simulated, its loop closes on the simulator's per-step pose (``/truth`` with full
    perception), which stands in for a localiser at camera rate, and it keeps the
    simulator's lockstep (:data:`SIM_EXECUTOR`). In the dome it closes its loop on the
    localiser's pose with tolerances above the localiser's error (:data:`DOME_EXECUTOR`),
    and its ``cmd_vel``, of the robot's ``drive_type``, goes to the robot's ``drive_topic``
    (the base).
    """
    ns = robot_namespace(k)
    pose = f"{TRUTH_PREFIX}/robot_{k}/pose" if dep.full and dep.sim else "pose"
    derived: dict[str, Any] = {
        "cell_size": geometry.cell_size,
        "pose_topic": pose,
        "seed": dep.seed * 1000 + k,
    }
    tuned = _sim_deadman(dep, profile)
    remaps: tuple[str, ...] = ()
    if dep.sim:
        derived["cmd_vel_stamp"] = SIM_EXECUTOR["cmd_vel_stamp"]
        tuned |= {n: v for n, v in SIM_EXECUTOR.items() if n != "cmd_vel_stamp"}
    else:
        robot = dep.site.robots[k]
        derived["drive_type"] = robot.drive_type
        tuned |= DOME_EXECUTOR
        remaps = (f"{ns}/cmd_vel:={robot.drive_topic}",)
    if robot_host(dep, k):
        derived["rearm_after_loss"] = True
    if profile.pose_timeout is not None:
        tuned["pose_timeout"] = profile.pose_timeout
    name = f"executor_{k}"
    return NodeSpec(
        name,
        "executor",
        _params(dep, "executor", name, derived, tuned, robot=k),
        (f"{ns}/executor",),
        namespace=ns,
        remaps=remaps,
        host=robot_host(dep, k),
    )


def team_tick(dep: Deployment, profile: TimingProfile, files: RunFiles) -> NodeSpec:
    """The team tick: last; its exit after ``steps`` ticks ends the run (0: never).

    Tick 0 waits for every controller's inputs (``wait_for_ready``) and, recording, for the
    recorder (the bag then holds every tick). Simulated it reads the simulator's blades; in
    the dome each blade driver's joint state, on the wall clock, and no node acknowledges
    its snapshot requests (the camera and the laser run anyway). Not restartable: a new one
    would start the ticks over.
    """
    derived: dict[str, Any] = {
        "robots": dep.robots,
        "steps": dep.steps,
        "seed": dep.seed,
        "scenario": dep.scenario,
        "blueprint": dep.blueprint,
        "word_timeout": float(dep.command_timeout),
        "wait_for_ready": True,
        "wait_for_recorder": bool(dep.record),
        "result_file": str(files.result),
    }
    if not dep.sim:
        derived |= {"blade_in": DOME_BLADE_IN, "blade_out": DOME_BLADE_OUT, "snapshot_ack": False}
    tuned: dict[str, Any] = {}
    if profile.blade_wait is not None:
        tuned["blade_wait"] = profile.blade_wait
    if profile.snapshot_retry is not None:
        tuned["snapshot_retry"] = profile.snapshot_retry
    first = dep.first_command_timeout or profile.first_word_timeout
    if first is not None:
        derived["first_word_timeout"] = float(first)
    return NodeSpec(
        "team_tick",
        "team_tick",
        _params(dep, "team_tick", "team_tick", derived, tuned),
        ("/team_tick",),
        restart=False,
        final=dep.steps > 0,
    )


def view(dep: Deployment, port: int) -> NodeSpec:
    """The live view (``ant-view``) of a site's run."""
    return NodeSpec(
        "view",
        "view",
        NodeParams(),
        ("/ant_view",),
        args=(
            "--site",
            str(Path(dep.site.path).resolve()),
            "--port",
            str(port),
            "--hardware",
            dep.hardware,
        ),
        module="excavation_bringup.view",
    )


# --- a rehearsal's emulated drivers (hardware: emulated) -------------------------------------


def world(dep: Deployment, profile: TimingProfile, files: RunFiles) -> NodeSpec:
    """A rehearsal's world: ``dynamics`` at real time behind the emulated drivers.

    Its per-step truth and its height maps (every :data:`WORLD_SNAPSHOT_PERIOD`, unasked) go
    under ``/truth`` for the emulated camera and laser; its own topics under
    :data:`WORLD_PREFIX`: the commands of the emulated bases and boards (the servo board
    holds a tick's blade bits, so set-points apply at once), the IMU readings the bases
    republish, the plant states the boards measure, and its clock (every node of the dome
    runs on the wall clock).
    """
    derived, tuned = _dynamics_values(dep, profile, files)
    derived |= {
        "pose_prefix": TRUTH_PREFIX,
        "snapshot_prefix": TRUTH_PREFIX,
        "time_factor": 1.0,
        "blade_after_motion": False,
    }
    tuned["snapshot_period"] = WORLD_SNAPSHOT_PERIOD
    remaps = [f"/clock:={WORLD_PREFIX}/clock"]
    for k in range(dep.robots):
        ns = robot_namespace(k)
        for topic in ("cmd_vel", "imu", "blade/servo_command", "blade/plant_state"):
            remaps.append(f"{ns}/{topic}:={WORLD_PREFIX}{ns}/{topic}")
    return NodeSpec(
        "world",
        "dynamics",
        _params(dep, "dynamics", "world", derived, tuned),
        ("/dynamics",),
        restart=False,
        remaps=tuple(remaps),
    )


def emulated_base(dep: Deployment, k: int) -> NodeSpec:
    """Robot ``k``'s base as diff_drive_controller: on the site's ``drive_topic`` and type.

    It drives the world's robot (``world/cmd_vel``) and, where the site says the robot
    carries an IMU, republishes the world's reading as the robot's ``imu``.
    """
    ns = robot_namespace(k)
    robot = dep.site.robots[k]
    derived = {"drive_type": robot.drive_type, "publish_imu": bool(robot.imu)}
    remaps = (
        f"{ns}/cmd_vel:={robot.drive_topic_resolved}",
        f"{ns}/world/cmd_vel:={WORLD_PREFIX}{ns}/cmd_vel",
        f"{ns}/world/imu:={WORLD_PREFIX}{ns}/imu",
    )
    return NodeSpec(
        f"base_{k}",
        "emulated_base",
        _params(dep, "emulated_base", f"base_{k}", derived, robot=k),
        (f"{ns}/base",),
        namespace=ns,
        remaps=remaps,
        host=robot_host(dep, k),
    )


def emulated_servo_board(dep: Deployment, k: int, files: RunFiles) -> NodeSpec:
    """Robot ``k``'s blade servo board on a pseudo-terminal, its port a link in the run dir."""
    ns = robot_namespace(k)
    derived = {"link": str(files.board_link(k)), "force_source": "world", "seed": dep.seed + k}
    remaps = (
        f"{ns}/world/servo_command:={WORLD_PREFIX}{ns}/blade/servo_command",
        f"{ns}/world/plant_state:={WORLD_PREFIX}{ns}/blade/plant_state",
    )
    return NodeSpec(
        f"servo_board_{k}",
        "emulated_servo_board",
        _params(dep, "emulated_servo_board", f"servo_board_{k}", derived, robot=k),
        (f"{ns}/servo_board",),
        namespace=ns,
        remaps=remaps,
        host=robot_host(dep, k),
    )


EMULATED_CAMERA_NS = "/overhead"
"""The emulated camera's namespace (its topics are remapped onto the site's)."""
EMULATED_LASER_NS = "/worksite"
"""The emulated laser's namespace (its topics are remapped onto the site's)."""


def emulated_camera(dep: Deployment, geometry: Geometry) -> NodeSpec:
    """The overhead camera driver on the site's topics and encoding, rendering ``/truth``."""
    c = dep.site.camera
    ns = EMULATED_CAMERA_NS
    derived: dict[str, Any] = {
        "robots": dep.robots,
        "truth_prefix": TRUTH_PREFIX,
        "rows": geometry.rows,
        "cols": geometry.cols,
        "cell_size": geometry.cell_size,
        "seed": dep.seed,
        "encoding": c.encoding,
    }
    image = f"{ns}/image_raw/compressed" if c.compressed else f"{ns}/image_raw"
    remaps = [f"{image}:={c.image_topic}"]
    if c.camera_info_topic:
        remaps.append(f"{ns}/camera_info:={c.camera_info_topic}")
    return NodeSpec(
        "camera",
        "emulated_camera",
        _params(dep, "emulated_camera", "camera", derived),
        (f"{ns}/camera",),
        namespace=ns,
        remaps=tuple(remaps),
    )


def emulated_laser(dep: Deployment, geometry: Geometry) -> NodeSpec:
    """The tilting laser and its mount where the site puts them, rendering ``/truth``."""
    las = dep.site.laser
    ns = EMULATED_LASER_NS
    derived: dict[str, Any] = {
        "robots": dep.robots,
        "truth_prefix": TRUTH_PREFIX,
        "rows": geometry.rows,
        "cols": geometry.cols,
        "cell_size": geometry.cell_size,
        "mount": [float(v) for v in las.mount],
        "sweep_scans": las.sweep_scans,
        "robot_height": float(las.robot_height),
        "seed": dep.seed,
    }
    remaps = (
        f"{ns}/scan:={las.scan_topic}",
        f"{ns}/laser_mount/joint_states:={las.mount_state_topic}",
    )
    return NodeSpec(
        "laser",
        "emulated_laser",
        _params(dep, "emulated_laser", "laser", derived),
        (f"{ns}/laser",),
        namespace=ns,
        remaps=remaps,
    )
