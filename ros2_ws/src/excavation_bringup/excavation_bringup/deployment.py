"""What a trial or a dome runs: one description, built from command-line arguments or a site.

A :class:`Deployment` says which graph to build (:mod:`excavation_bringup.graph`) and how to
launch it (:mod:`excavation_bringup.launch`): the drive (``grid``: the lockstep simulator
applies each word at once; ``continuous``: drive executors, the team tick and the
continuous-motion simulator), the perception (``truth``: the simulator's poses and heights;
``full``: camera + localiser, laser + mapper), the hardware (``sim``: the simulator stands in
for the robots; ``dome``: the site's drivers; ``emulated``: the dome's table against emulated
drivers in front of the simulated world, ``ant-dome rehearse``), the supervisor
(``internal``: started and armed; ``external``: an operator's), recording, and the launcher
(composed in one process, or a process per node). ``ant-trial`` builds one from its
options; ``ant-dome`` from a site file (:meth:`Deployment.from_site`), which then supplies
topics, offsets, the LED table and each robot's genome. :meth:`Deployment.check` refuses
combinations that cannot run.

Pure module: no ``rclpy``.
"""

from __future__ import annotations

from dataclasses import dataclass

from excavation_bringup import site as sitefile
from excavation_sim.soil import SoilError, check_soil

DRIVES = ("grid", "continuous")
PERCEPTIONS = ("truth", "full")
HARDWARE = ("sim", "dome", "emulated")
SUPERVISORS = ("internal", "external")


class DeploymentError(ValueError):
    """A deployment that cannot run (the message names the option and its value)."""


@dataclass(frozen=True)
class Deployment:
    """One trial or dome run, resolved.

    Attributes:
        controller: A genome file or ``"hand-coded"`` for every robot (a site: each robot's
            own, ``site.robots[k].genome``; then empty).
        robots: Team size.
        steps: Ticks to run (the dome: 0 runs until stopped).
        seed: Scenario seed (as ``ant-eval --seed``).
        blueprint: Blueprint spec of the server and the simulator.
        scenario: Scenario index of ``seed``.
        domain: ROS domain id.
        command_timeout: Wall seconds a tick waits for every controller's word.
        timeout: Wall seconds after which a trial gives up.
        blade_driver: One blade driver per robot (the lockstep simulator can play the
            blade itself; the continuous drive needs them).
        record: Bag directory to record into, or ``None``.
        perception: ``truth`` or ``full``.
        supervisor: ``internal`` or ``external``.
        occlude: LEDs hidden from the synthetic camera (``"2:front,2:rear"``).
        drive: ``grid`` or ``continuous``.
        exact: The continuous-motion simulator without slip and noise (the parity setting).
        soil: The continuous-motion simulator's soil: ``grid`` (the world model's rules)
            or ``physical`` (:mod:`excavation_sim.soil`).
        processes: Each node in its own process (else composed in this one).
        hardware: ``sim``, ``dome`` or ``emulated`` (the dome's table, unchanged, against
            :mod:`dome_emulator`'s drivers and the continuous-motion world on the wall
            clock).
        site: The site file the run comes from (``ant-dome``), or ``None``.
        first_command_timeout: Wall seconds tick 0 waits for the words (``None``: the
            timing profile's).
        time_factor: The simulator's clock at most this many times real time (0: as fast
            as the team answers); nodes in other processes that follow sim time need it.
    """

    controller: str
    robots: int
    steps: int
    seed: int
    blueprint: str = "default"
    scenario: int = 0
    domain: int = 0
    command_timeout: float = 2.0
    timeout: float = 600.0
    blade_driver: bool = True
    record: str | None = None
    perception: str = "truth"
    supervisor: str = "internal"
    occlude: str = ""
    drive: str = "grid"
    exact: bool = False
    soil: str = "grid"
    processes: bool = False
    hardware: str = "sim"
    site: sitefile.Site | None = None
    first_command_timeout: float | None = None
    time_factor: float = 0.0

    @property
    def full(self) -> bool:
        """Controllers see the world only through the localiser and the mapper."""
        return self.perception == "full"

    @property
    def sim(self) -> bool:
        """The simulator stands in for the robots."""
        return self.hardware == "sim"

    @property
    def emulated(self) -> bool:
        """The dome's table against emulated drivers (a rehearsal)."""
        return self.hardware == "emulated"

    @property
    def profile_name(self) -> str:
        """The timing profile (:mod:`excavation_bringup.profiles`) this run uses."""
        if not self.sim:
            return "dome"
        return "processes" if self.processes else "composed"

    def robot_controller(self, k: int) -> str:
        """Robot ``k``'s controller: a genome file or ``"hand-coded"``."""
        return self.site.robots[k].genome if self.site is not None else self.controller

    def check(self) -> None:
        """Refuse what cannot run.

        Raises:
            DeploymentError: Naming the option and the value.
        """
        for name, value, choices in (
            ("drive", self.drive, DRIVES),
            ("perception", self.perception, PERCEPTIONS),
            ("hardware", self.hardware, HARDWARE),
            ("supervisor", self.supervisor, SUPERVISORS),
        ):
            if value not in choices:
                raise DeploymentError(
                    f"{name} = {value!r}: expected one of {', '.join(map(repr, choices))}"
                )
        try:
            check_soil(self.soil)
        except SoilError as e:
            raise DeploymentError(str(e)) from None
        if self.occlude and not self.full:
            raise DeploymentError(
                "occlude: hides a robot from the camera, so needs perception 'full'"
            )
        if self.soil != "grid" and self.drive != "continuous":
            raise DeploymentError(
                f"soil: {self.soil} is a mode of the continuous-motion simulator "
                "(drive: continuous)"
            )
        if self.drive == "continuous" and not self.blade_driver:
            raise DeploymentError(
                "drive: continuous runs with blade drivers (the blade's tick interface)"
            )
        if not self.sim and (self.drive != "continuous" or not self.full or self.site is None):
            raise DeploymentError(
                f"hardware: {self.hardware} runs a site file's continuous drive with full "
                "perception"
            )
        if not self.sim and not self.processes:
            raise DeploymentError(f"hardware: {self.hardware} runs every node as its own process")

    @classmethod
    def from_site(
        cls,
        site: sitefile.Site,
        hardware: str,
        ticks: int | None = None,
        record: str | None = None,
        domain: int | None = None,
    ) -> Deployment:
        """The run ``ant-dome up SITE`` (``--sim``) or ``ant-dome rehearse SITE`` starts.

        Args:
            site: The checked site.
            hardware: ``dome`` (``up``), ``sim`` (``up --sim``) or ``emulated``
                (``rehearse``).
            ticks: Ticks to run (default: simulated or emulated the site's ``sim.ticks``;
                the dome runs until stopped, 0).
            record: ``--record``'s bag directory.
            domain: ``--domain`` (default: the site's).
        """
        s = site.sim
        sim = hardware != "dome"  # a simulated world: the site's scenario and its ticks
        return cls(
            controller="",
            robots=site.n_robots,
            steps=int((ticks or s.ticks) if sim else (ticks or 0)),
            seed=s.seed,
            blueprint=site.worksite.blueprint,
            scenario=s.scenario,
            domain=site.network.domain if domain is None else domain,
            command_timeout=float(s.command_timeout),
            timeout=0.0,
            blade_driver=True,
            record=record,
            perception="full",
            supervisor="internal",
            drive="continuous",
            exact=s.exact,
            soil=s.soil,
            processes=True,
            hardware=hardware,
            site=site,
            first_command_timeout=float(s.first_command_timeout) if hardware == "sim" else None,
        )
