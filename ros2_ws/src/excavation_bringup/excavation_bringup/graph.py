"""The trial graph: which nodes a run starts, in what order. The only place a run is assembled.

:func:`build` takes a :class:`~excavation_bringup.deployment.Deployment` and a run directory
and returns a :class:`Graph`, a list of node specs in start order (stopped in reverse) made
by the node spec functions of :mod:`excavation_bringup.nodes` with the deployment's timing
profile. Two shapes:

* :func:`lockstep` (``drive: grid``): the recorder, the supervisor, the blueprint server,
  the lockstep simulator (the final node), with full perception the synthetic sensors,
  the localiser and the mapper, then per robot a controller and a blade driver.
* :func:`continuous` (``drive: continuous``; ``ant-trial --drive continuous`` and every
  ``ant-dome up``): the recorder; simulated, ``dynamics`` (the clock) and the drive
  executors, which it waits for before its first step; the supervisor, the server, the
  synthetic sensors (simulated), the localiser and the mapper; per robot a blade driver;
  in the dome the executors; per robot a controller; the team tick (final); the live view.
  A rehearsal (``hardware: emulated``, ``ant-dome rehearse``) starts the simulated world
  (``dynamics`` at real time) and the emulated drivers (a base and a servo board per robot,
  the overhead camera, the tilting laser) first, then exactly the dome's table.
  ``ant-dome up SITE --sim`` and ``ant-trial --drive continuous --perception full
  --processes`` are this one function, so they run the same graph by construction.

Either launcher (:mod:`excavation_bringup.launch`) runs a graph: composed in one process, or
each node as a process with its parameters in a file.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import yaml

from excavation_bringup import nodes
from excavation_bringup import site as sitefile
from excavation_bringup.deployment import Deployment
from excavation_bringup.profiles import PROFILES, TimingProfile
from excavation_common.errors import FieldError
from excavation_common.files import write_text_atomic

OWN_CLOCK = ("dynamics", "recorder", "view")
"""Node kinds on their own clock beside the continuous-motion simulator: ``dynamics`` is
the clock, the recorder and the live view stamp what they see on the wall clock; every
other node runs on the simulator's ``/clock`` (``use_sim_time``)."""


class GraphError(ValueError):
    """A graph whose nodes would refuse their parameters: every problem, one per line.

    Attributes:
        problems: One :class:`~excavation_common.errors.FieldError` each (a site's refused
            ``overrides:`` name the file and ``overrides.KIND.NAME``).
    """

    def __init__(self, problems: list[FieldError]) -> None:
        self.problems = list(problems)
        super().__init__("\n".join(map(str, self.problems)))


@dataclass
class Graph:
    """A run's nodes in start order, with the files they share.

    Attributes:
        deployment: What it runs.
        profile: Its timing profile.
        files: Its run directory's files.
        nodes: Node specs in start order.
    """

    deployment: Deployment
    profile: TimingProfile
    files: nodes.RunFiles
    nodes: list[nodes.NodeSpec] = field(default_factory=list)

    @property
    def final(self) -> str:
        """The node whose exit ends the run (empty when none does: the dome without ticks)."""
        return next((n.name for n in self.nodes if n.final), "")

    def spec(self, name: str) -> nodes.NodeSpec:
        """The node called ``name``.

        Raises:
            KeyError: No such node.
        """
        for n in self.nodes:
            if n.name == name:
                return n
        raise KeyError(f"no node {name!r} in the graph ({', '.join(self.names)})")

    @property
    def names(self) -> list[str]:
        """Node names in start order."""
        return [n.name for n in self.nodes]

    @property
    def hosts(self) -> list[str]:
        """The site's hosts, the dome PC first (``["dome"]`` without a site)."""
        site = self.deployment.site
        return [h.name for h in site.hosts] if site is not None else [sitefile.DOME_PC.name]

    def problems(self) -> list[FieldError]:
        """What its nodes would refuse, one error each.

        The site's refused overrides (one refused on each robot's node is listed once) and a
        second ``/worksite/map_info`` publisher (only the blueprint server publishes it).
        """
        out: list[FieldError] = []
        for spec in self.nodes:
            out += [e for e in spec.params.problems if str(e) not in map(str, out)]
            publishes = "publish_map_info" in spec.params and spec.params["publish_map_info"]
            if spec.kind != sitefile.MAP_INFO_OWNER and publishes:
                site = self.deployment.site
                out.append(
                    sitefile.SiteError(
                        site.path if site is not None else "",
                        f"overrides.{spec.kind}.publish_map_info",
                        True,
                        "more than one map_info publisher: the blueprint server publishes "
                        "/worksite/map_info",
                    )
                )
        return out

    def check(self) -> Graph:
        """This graph, if no node would refuse its parameters.

        Raises:
            GraphError: Every problem of :meth:`problems`.
        """
        problems = self.problems()
        if problems:
            raise GraphError(problems)
        return self

    def share(self, host: str) -> list[nodes.NodeSpec]:
        """The nodes ``host`` runs, in start order (the dome PC: every node of no host).

        Raises:
            KeyError: ``host`` is not one of :attr:`hosts`.
        """
        if host not in self.hosts:
            raise KeyError(f"no host {host!r} in the site (hosts: {', '.join(self.hosts)})")
        own = "" if host == self.hosts[0] else host
        return [n for n in self.nodes if n.host == own]


def _calibration(dep: Deployment, run_dir: Path) -> str:
    """The camera model the localiser loads; the synthetic camera's is written now.

    As in the field: marks at known places are "clicked" in a frame of the synthetic
    camera (with pixel noise) and the model is fitted to them
    (:func:`excavation_bringup.perception.simulated_calibration`).
    """
    site = dep.site
    if not dep.full:
        return ""
    if site is not None and site.camera.calibration != sitefile.SIMULATED:
        return site.camera.calibration
    from blueprint_server.blueprint import resolve_blueprint
    from excavation_bringup.perception import simulated_calibration
    from overhead_localizer.camera_model import save_model

    path = run_dir / "camera.yaml"
    # The emulated camera driver publishes its intrinsics: fit the pose under them.
    camera_info = bool(site is not None and site.camera.camera_info_topic and dep.emulated)
    model = simulated_calibration(resolve_blueprint(dep.blueprint), dep.seed, camera_info)
    save_model(model, str(path))
    return str(path)


def prepare(dep: Deployment, run_dir: str | Path) -> nodes.RunFiles:
    """Create ``run_dir`` and write what the nodes read (calibration, a site's LED table)."""
    run_dir = Path(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    files = nodes.RunFiles(run_dir, _calibration(dep, run_dir))
    if dep.site is not None:
        document = sitefile.beacons_document(dep.site)
        write_text_atomic(files.beacons, yaml.safe_dump(document, sort_keys=False))
    return files


def lockstep(dep: Deployment, run_dir: str | Path) -> Graph:
    """The grid trial's graph (``ant-trial``, ``drive: grid``)."""
    profile = PROFILES[dep.profile_name]
    graph = Graph(dep, profile, prepare(dep, run_dir))
    geometry = nodes.Geometry(dep)
    add = graph.nodes.append
    if dep.record:
        add(nodes.recorder(dep, geometry))
    if dep.supervisor == "internal":
        add(nodes.supervisor(dep))
    add(nodes.server(dep))
    add(nodes.sim(dep, graph.files, dep.processes))
    if dep.full:
        add(nodes.sensors(dep, geometry))
        add(nodes.localizer(dep, graph.files))
        add(nodes.mapper(dep, profile, geometry))
    for k in range(dep.robots):
        add(nodes.controller(dep, k, geometry))
        if dep.blade_driver:
            add(nodes.blade_driver(dep, k, profile, graph.files))
    return graph


def continuous(
    dep: Deployment, run_dir: str | Path, view: bool = False, view_port: int = 8765
) -> Graph:
    """The continuous-motion graph: ``ant-trial --drive continuous`` and ``ant-dome up``.

    Simulated, ``dynamics`` and the executors start first: ``dynamics`` is the clock of
    every other node and starts stepping once every executor is on the graph, so that the
    timers of the nodes after them run. Nothing moves before the supervisor arms the team
    and the team tick grants a goal.
    """
    profile = PROFILES[dep.profile_name]
    graph = Graph(dep, profile, prepare(dep, run_dir))
    geometry = nodes.Geometry(dep)
    add = graph.nodes.append
    robots = range(dep.robots)
    if dep.record:
        add(nodes.recorder(dep, geometry))
    if dep.emulated:  # a rehearsal: the world and the emulated drivers, then the dome's table
        add(nodes.world(dep, profile, graph.files))
        for k in robots:
            add(nodes.emulated_base(dep, k))
            add(nodes.emulated_servo_board(dep, k, graph.files))
        add(nodes.emulated_camera(dep, geometry))
        add(nodes.emulated_laser(dep, geometry))
    if dep.sim:
        add(nodes.dynamics(dep, profile, graph.files))
        for k in robots:
            add(nodes.executor(dep, k, profile, geometry))
    if dep.supervisor == "internal":
        add(nodes.supervisor(dep))
    add(nodes.server(dep))
    if dep.full:
        if dep.sim:
            add(nodes.sensors(dep, geometry))
        add(nodes.localizer(dep, graph.files, view))
        add(nodes.mapper(dep, profile, geometry))
    for k in robots:
        add(nodes.blade_driver(dep, k, profile, graph.files))
    if not dep.sim:
        for k in robots:
            add(nodes.executor(dep, k, profile, geometry))
    for k in robots:
        add(nodes.controller(dep, k, geometry))
    add(nodes.team_tick(dep, profile, graph.files))
    if view:
        add(nodes.view(dep, view_port))
    if dep.sim:  # the continuous-motion simulator is the clock of every other node
        graph.nodes = [replace(n, sim_time=n.kind not in OWN_CLOCK) for n in graph.nodes]
    return graph


def build(dep: Deployment, run_dir: str | Path, view: bool = False, view_port: int = 8765) -> Graph:
    """The graph of ``dep`` (checked first).

    Raises:
        excavation_bringup.deployment.DeploymentError: ``dep`` cannot run.
        GraphError: A node would refuse its parameters (a site's overrides).
    """
    dep.check()
    if dep.drive == "grid":
        return lockstep(dep, run_dir).check()
    return continuous(dep, run_dir, view, view_port).check()
