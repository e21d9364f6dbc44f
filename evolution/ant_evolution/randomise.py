"""Domain randomisation for training: per-scenario worlds the controller must not rely on.

Jakobi's envelope of noise, as the reality-gap literature applies it: a controller evolved
in one exact world learns that world's accidents (the grid's push capacity of 12 units, a
climb limit of exactly one, sensors that never misread). A *randomised* scenario draws,
from its own seeded stream, the things the real robots do not promise:

* the grid's push capacities without and with throttle-up: the rules' own times 2/3 .. 4/3,
  rounded (the throttle's at least the normal's);
* the grid's climb limits: the rules' own or one more, evenly (the throttle's at least the
  normal's);
* the grid blade's fill rule (``soil_fill``): on or off, evenly;
* sensing, in both worlds: a Z sensor over a dig cell within a unit of its goal reads it a
  unit off with a chance drawn per scenario in 0 .. 0.2; a set U1 reads 0 with a chance in
  0 .. 0.3 (:func:`excavation_sim.world.sensor_noise`);
* the physical soil: its angle of repose and internal friction angle times 0.85 .. 1.15,
  its bulk density times 0.8 .. 1.25, the robot's push (motors, traction, blade limit)
  times 0.7 .. 1.3, and the blade's epsilon rule on or off, evenly.

Scenario ``i`` of seed ``K`` draws them from ``SeedSequence([K, i, STREAM])``, a stream of
its own: the placements and random turns (``SeedSequence(K).spawn(S)[i]``) are the ones the
same scenario has unrandomised, so a randomised and a plain run see the same starts. The
draws happen where the scenarios are made, before any worker sees them, so a randomised run
gives the same history with any number of workers and resumes bit for bit.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from excavation_sim.cell_soil import X_BLADE_LIMIT, X_MOTOR0, X_MOTOR1, X_TRACTION
from excavation_sim.rules import CHANCE_ONE, P_MISREAD, P_U1_DROPOUT, WorldRules
from excavation_sim.soil import SoilParams

STREAM = 0x52414E44
"""The randomisation's seed-sequence word (``"RAND"``): its draws never meet the scenario's."""


@dataclass(frozen=True)
class Ranges:
    """The randomisation's ranges (the module docstring's table).

    Attributes:
        load_scale: Push capacities' factor range.
        climb_extra: Largest extra climb (each limit gets 0 .. this, evenly).
        fill_chance: Chance that the fill rule is on.
        misread: Range of a scenario's Z misreading chance.
        u1_dropout: Range of a scenario's U1 dropout chance.
        repose, friction, density, push: The physical soil's factor ranges.
        epsilon_chance: Chance that the physical blade's epsilon rule is on.
    """

    load_scale: tuple[float, float] = (2 / 3, 4 / 3)
    climb_extra: int = 1
    fill_chance: float = 0.5
    misread: tuple[float, float] = (0.0, 0.2)
    u1_dropout: tuple[float, float] = (0.0, 0.3)
    repose: tuple[float, float] = (0.85, 1.15)
    friction: tuple[float, float] = (0.85, 1.15)
    density: tuple[float, float] = (0.8, 1.25)
    push: tuple[float, float] = (0.7, 1.3)
    epsilon_chance: float = 0.5


RANGES = Ranges()
"""The documented ranges every randomised run uses."""


@dataclass(frozen=True)
class Draw:
    """One scenario's randomised world: its rules, noise chances and soil factors."""

    rules: WorldRules
    misread: float
    u1_dropout: float
    repose: float
    friction: float
    density: float
    push: float
    epsilon: bool


def draw(rules: WorldRules, seed: int, index: int, ranges: Ranges = RANGES) -> Draw:
    """Scenario ``index`` of ``seed``'s randomised world around ``rules``."""
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), int(index), STREAM]))
    lo, hi = ranges.load_scale
    normal = max(1, round(rules.normal_load * rng.uniform(lo, hi)))
    throttle = max(normal, round(rules.throttle_load * rng.uniform(lo, hi)))
    normal_climb = rules.normal_climb + int(rng.integers(0, ranges.climb_extra + 1))
    throttle_climb = max(
        normal_climb, rules.throttle_climb + int(rng.integers(0, ranges.climb_extra + 1))
    )
    drawn = dataclasses.replace(
        rules,
        normal_load=int(normal),
        throttle_load=int(throttle),
        normal_climb=normal_climb,
        throttle_climb=throttle_climb,
        soil_fill=bool(rng.random() < ranges.fill_chance),
    )
    return Draw(
        rules=drawn,
        misread=float(rng.uniform(*ranges.misread)),
        u1_dropout=float(rng.uniform(*ranges.u1_dropout)),
        repose=float(rng.uniform(*ranges.repose)),
        friction=float(rng.uniform(*ranges.friction)),
        density=float(rng.uniform(*ranges.density)),
        push=float(rng.uniform(*ranges.push)),
        epsilon=bool(rng.random() < ranges.epsilon_chance),
    )


def packed(d: Draw) -> np.ndarray:
    """The draw's packed rules with its noise chances (``int64 [N_PACKED]``, writable)."""
    out = d.rules.as_array().copy()
    out[P_MISREAD] = round(d.misread * CHANCE_ONE)
    out[P_U1_DROPOUT] = round(d.u1_dropout * CHANCE_ONE)
    return out


def soil_spec(soil: str, d: Draw) -> str:
    """``soil`` (a physical soil spec) with the draw's repose, friction, density and epsilon.

    The factors scale the soil's own resolved values; the push factor acts on the
    constants afterwards (:func:`scale_push`).
    """
    base = SoilParams(soil=soil).resolved()
    extra = (
        f"repose_angle={min(base.repose_angle * d.repose, 80.0):.6g}",
        f"friction_angle={min(base.friction_angle * d.friction, 70.0):.6g}",
        f"density={base.density * d.density:.6g}",
        f"epsilon={'true' if d.epsilon else 'false'}",
    )
    return ",".join((soil, *extra))


def scale_push(physics: np.ndarray, factor: float) -> None:
    """Scale the robot's push in a physics vector in place: motor, traction, blade limit."""
    for x in (X_MOTOR0, X_MOTOR1, X_TRACTION, X_BLADE_LIMIT):
        physics[x] *= factor
