"""A controller as the field sees it: sensor vector in, behaviour mask out, memory bit kept.

:class:`Controller` wraps what decides (a compiled ANT tissue or the hand-coded rules).
:class:`ControllerCore` is the per-robot state machine a ROS controller node runs: from
arrays decoded from messages (heights and goal in soil units, zones, poses, blade code and
load, stuck flag) it computes the sensor vector with :func:`ant_controller.sensing.sense`,
the same function the simulator uses, asks the controller, and updates the memory bit with
the simulator's own rule (:func:`ant_controller.memory.next_memory`). R1 (tilt) is the
IMU's when the caller passes it (``tilted``), else computed from the height map as in the
simulator. ``tests/test_controller_core.py`` runs whole
episodes through messages and this core and gets the offline evaluator's results exactly.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ant_controller.genome import Genome, TissueGene
from ant_controller.genome_io import load_genome
from ant_controller.hand_coded import HandCodedRules, hand_coded_program
from ant_controller.layout import N_SENSORS
from ant_controller.memory import next_memory
from ant_controller.readings import H1_RELATIVE, HAND_CODED_READINGS, ReadingError
from ant_controller.sensing import is_tilted_down, sensor_vector
from ant_controller.tissue import CompiledTissue, TissueRecord, compile_tissue, decide

KIND_ANT = 0
KIND_HAND_CODED = 1


@dataclass(frozen=True)
class Controller:
    """What decides a robot's behaviours: a compiled ANT tissue or the hand-coded rules.

    Attributes:
        kind: ``KIND_ANT`` or ``KIND_HAND_CODED``.
        tissue: The compiled tissue (an empty one for the hand-coded controller).
        name: Label for reports.
        robots: The genome's N gene, if it has one.
        union: Hand-coded only: the paper's reading of the rules (rules 3-11 as a union),
            else the first-match chain (:mod:`ant_controller.hand_coded`).
    """

    kind: int
    tissue: CompiledTissue
    name: str
    robots: int | None = None
    union: bool = False

    @classmethod
    def from_genome(cls, genome: Genome, name: str = "genome") -> Controller:
        """Compile a genome once into a controller."""
        return cls(KIND_ANT, compile_tissue(genome), name, genome.tissue.robots)

    @classmethod
    def from_file(cls, path: str | Path) -> Controller:
        """Load, validate and compile a genome file (``GenomeFormatError`` when bad)."""
        return cls.from_genome(load_genome(path), name=str(path))

    @classmethod
    def from_spec(cls, spec: str) -> Controller:
        """``hand-coded`` (the appendix's rules) or a genome file's path, as the CLIs take it.

        Raises:
            GenomeFormatError: A bad genome file.
            OSError: A genome file that cannot be read.
        """
        return cls.hand_coded() if spec == "hand-coded" else cls.from_file(spec)

    @classmethod
    def hand_coded(cls, reading: str = "chain") -> Controller:
        """The appendix's hand-coded controller (``reading``: ``"chain"`` or ``"union"``).

        Raises:
            ReadingError: For another reading.
        """
        if reading not in HAND_CODED_READINGS:
            raise ReadingError(
                "<arguments>", "hand_coded", reading, f"must be one of {HAND_CODED_READINGS}"
            )
        union = reading == "union"
        name = "hand-coded (union)" if union else "hand-coded"
        return cls(KIND_HAND_CODED, _EMPTY_TISSUE, name, union=union)

    def record(self) -> TissueRecord | HandCodedRules:
        """The decision program as the kernels take it (a tissue record or the rules)."""
        if self.kind == KIND_HAND_CODED:
            return HandCodedRules(self.union)
        return self.tissue.record()

    def decide(self, codes: np.ndarray) -> int:
        """Behaviour mask for one sensor vector."""
        c = np.asarray(codes, dtype=np.int64)
        if self.kind == KIND_HAND_CODED:
            return int(hand_coded_program(c, HandCodedRules(self.union)))
        return int(decide(c, self.tissue.record()))


_EMPTY_TISSUE = compile_tissue(Genome(tissue=TissueGene(), cells=()))


@dataclass
class ControllerCore:
    """One robot's controller state between ticks.

    Attributes:
        controller: What decides.
        memory: The memory bit M1.
        h1_frame: H1 relative to the robot's heading or on the compass
            (:mod:`ant_controller.readings`: ``ControllerReadings.h1_frame``).
    """

    controller: Controller
    memory: int = 0
    h1_frame: int = H1_RELATIVE
    _codes: np.ndarray = field(default_factory=lambda: np.zeros(N_SENSORS, dtype=np.int64))

    def decide(
        self,
        heights: np.ndarray,
        zones: np.ndarray,
        goal: np.ndarray,
        poses: np.ndarray,
        k: int,
        blade: int,
        load_volume: int,
        stuck: bool,
        active: np.ndarray | None = None,
        tilted: bool | None = None,
    ) -> int:
        """Behaviour mask for robot ``k`` this tick; updates the memory bit.

        Args:
            heights: Soil heights in soil units, ``[rows, cols]``.
            zones: Blueprint zones.
            goal: Goal heights in soil units.
            poses: ``[n, 3]`` ``(row, col, heading)`` of every robot (k is this one).
            k: This robot's index in ``poses``.
            blade: B1 code.
            load_volume: Soil units against the blade (from the push force).
            stuck: U1 as reported by the robot (or the simulator).
            active: Robots to take into account (default: all).
            tilted: R1 as the robot's IMU reports it; ``None``: the world model's rule on
                ``heights`` under the footprint.
        """
        poses = np.ascontiguousarray(poses, dtype=np.int64)
        heights = np.ascontiguousarray(heights, dtype=np.int32)
        if tilted is None:
            row, col, heading = poses[k]
            tilted = is_tilted_down(heights, row, col, heading)
        self._codes = sensor_vector(
            heights,
            zones,
            goal,
            poses,
            k,
            blade=blade,
            load_volume=load_volume,
            stuck=bool(stuck),
            tilted=bool(tilted),
            memory=bool(self.memory),
            active=active,
            h1_frame=self.h1_frame,
        )
        mask = self.controller.decide(self._codes)
        self.memory = int(next_memory(self.memory, mask))
        return mask

    @property
    def codes(self) -> np.ndarray:
        """The last sensor vector (a copy)."""
        return self._codes.copy()
