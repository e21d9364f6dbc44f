"""Physical soil for the continuous-motion simulator (``soil: physical``).

The soil that can disagree with the grid: a height field ``subcells`` times finer than the
grid in whole quanta (conserved exactly), cut and pushed by a blade that moves with the
robot's continuous pose, held at an angle of repose, resisting the blade with McKyes's
earth-moving equation plus a drag prism, against a robot whose push comes from its motors
and traction. docs/world-model.md, "Physical soil", is the specification: the blade, repose,
resistance, calibration, traction, force control, the presets and their sources, and which
departures from the grid are physics.

Use: :func:`parse_soil` / :func:`soil_arg` read a spec (``grid`` or
``physical[:PRESET][,KEY=VALUE...]``; the presets live in ``soil_presets.yaml`` beside this
module, each value with its source) into :class:`SoilParams`; :class:`Soil` holds a site's
field and moves it (``cut``, ``relax``, ``relief``); :func:`blade_force` and
:func:`n_factors` are the force model, :func:`calibrate` and :func:`stall_capacity` tie it to
the grid's capacities or measure the robot's. The numba kernels here are shared with the
offline physical world (:mod:`excavation_sim.cell_soil`); ``python -m
excavation_sim.presets`` prints the presets' tables.

Pure module (numpy, numba); no ``rclpy``.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass, fields, replace
from functools import lru_cache
from pathlib import Path

import numba as nb
import numpy as np
import yaml

from excavation_common.constants import SOIL_MODES
from excavation_common.params import ParameterError, defaults, param, validate

MAX_FINE_CELLS = 4_000_000
"""Largest fine field (sub-cells) a world may ask for: checked before allocating."""


class SoilError(ValueError):
    """Physical-soil parameters that cannot describe a soil or a site."""


@dataclass(frozen=True)
class SoilParams:
    """The soil and the blade of ``soil: physical`` (node parameters of ``dynamics``).

    Defaults: dry loose sand (bulk density 1,600 kg/m^3, no cohesion, internal friction
    35 degrees, repose 33 degrees, soil-steel friction two thirds of the internal angle;
    McKyes 1985, table 4.1 ranges for loose sands), calibrated to the grid. The presets of
    ``soil_presets.yaml`` (``soil: physical:dome``, ``physical:lunar``) set sourced values
    for the paper's two real worlds (docs/world-model.md, "Presets").
    """

    soil: str = param(
        "grid",
        "soil model: grid (the world model's rules) or physical[:PRESET][,KEY=VALUE...] "
        "(presets: grid, dome, lunar; keys: the parameters below)",
    )
    subcells: int = param(4, "sub-cells per cell side (soil: physical)", low=1, high=16)
    quanta: int = param(1000, "height quanta per soil unit (soil: physical)", low=1, high=10**6)
    density: float = param(1600.0, "soil bulk density, kg/m^3", low=1.0, high=1e5)
    gravity: float = param(9.81, "gravity, m/s^2 (the Moon: 1.62)", low=0.01, high=100.0)
    cohesion: float = param(0.0, "soil cohesion, Pa", low=0.0, high=1e6)
    friction_angle: float = param(35.0, "soil internal friction angle, deg", low=1.0, high=70.0)
    blade_friction_angle: float = param(23.0, "soil-blade friction angle, deg", low=0.0, high=60.0)
    rake_angle: float = param(
        60.0, "blade rake angle from the horizontal, deg", low=10.0, high=90.0
    )
    repose_angle: float = param(33.0, "angle of repose, deg", low=1.0, high=80.0)
    blade_height: float = param(
        0.45, "blade height above its edge, m: soil above it falls over", low=0.01, high=10.0
    )
    pile_reach: float = param(
        1.5,
        "cells ahead of the blade whose loose soil above the edge it pushes (the drag prism; "
        "also the held volume V_blade)",
        low=0.25,
        high=8.0,
    )
    end_plates: float = param(
        0.0,
        "length of end plates ahead of the blade's ends, cells (0: a straight blade)",
        low=0.0,
        high=4.0,
    )
    wheel_friction: float = param(0.6, "wheel-soil friction coefficient", low=0.01, high=3.0)
    traction_margin: float = param(
        1.25, "wheel traction over the throttle-up motor force (sets the mass)", low=1.0
    )
    relax_passes: int = param(2, "repose sweeps per simulator step", low=1, high=64)
    # The robot (calibration: robot; docs/world-model.md, "Presets").
    calibration: str = param(
        "grid",
        "motor forces from the grid's push capacities (grid) or from the robot below (robot)",
        choices=("grid", "robot"),
    )
    robot_mass: float = param(15.0, "calibration robot: robot mass, kg", low=0.01, high=1e6)
    drive_power: float = param(
        0.0,
        "calibration robot: drive power, W (0: the wheels' traction limits the push)",
        low=0.0,
        high=1e7,
    )
    push_speed: float = param(
        0.15, "calibration robot: speed at which drive_power pushes, m/s", low=0.001, high=10.0
    )
    normal_fraction: float = param(
        0.5,
        "calibration robot: push without throttle-up, share of the full push",
        low=0.01,
        high=1.0,
    )
    blade_limit: float = param(
        0.0, "calibration robot: most force the blade takes, N (0: no limit)", low=0.0, high=1e7
    )
    force_control: bool = param(
        False,
        "over blade_limit the blade rises until its force is within the limit (a PID on the "
        "blade's force, as the dome robots'); off: the push stalls",
    )
    load_full_scale: float = param(
        0.0,
        "force that L1 reads as a full blade, N (0: the full push of the robot)",
        low=0.0,
        high=1e7,
    )
    traction: str = param(
        "coulomb",
        "wheels: coulomb (wheel_friction m g, all or nothing) or terramechanics (Bekker "
        "sinkage and rolling resistance, Janosi-Hanamoto slip)",
        choices=("coulomb", "terramechanics"),
    )
    bekker_n: float = param(1.1, "Bekker sinkage exponent n", low=0.1, high=3.0)
    bekker_kc: float = param(990.0, "Bekker cohesive modulus k_c, N/m^(n+1)", low=0.0, high=1e9)
    bekker_kphi: float = param(
        1.52843e6, "Bekker frictional modulus k_phi, N/m^(n+2)", low=1.0, high=1e10
    )
    shear_cohesion: float = param(
        1040.0, "traction: the soil's cohesion under the wheels, Pa", low=0.0, high=1e6
    )
    shear_friction_angle: float = param(
        28.0, "traction: the soil's friction angle under the wheels, deg", low=1.0, high=70.0
    )
    janosi_k: float = param(
        0.025, "Janosi-Hanamoto shear deformation modulus K, m", low=1e-4, high=1.0
    )
    contact_width: float = param(
        0.05, "traction: width of each side's running gear, m", low=0.001, high=10.0
    )
    contact_length: float = param(
        0.3, "traction: length of each side's ground contact, m", low=0.001, high=20.0
    )
    # Switches of the departures from the grid (docs/world-model.md, "What the physical
    # soil keeps and what it fixed"); the attribution study turns each one alone.
    fill: bool = param(True, "a carrying blade fills hollows below its edge (physics)")
    epsilon: bool = param(True, "the paper's epsilon rule: an empty blade set above cuts as level")
    refusals: bool = param(
        True, "an engaged blade refuses a move that pushes into a robot or off the site"
    )
    load: str = param(
        "force",
        "what L1 reads: force (the blade's force) or volume (the grid's V_blade)",
        choices=("force", "volume"),
    )
    fitness_heights: str = param(
        "mean",
        "what the fitness reads: mean (the sub-cell means) or rounded (whole units)",
        choices=("mean", "rounded"),
    )
    repose: bool = param(True, "slopes relax to the angle of repose")

    def check(self) -> None:
        """Cross-field rules: the blade and the soil must admit a failure plane.

        Raises:
            SoilError: Naming the angles, or the part of ``soil`` that is not a soil.
        """
        parse_soil(self.soil)
        if self.blade_friction_angle >= self.friction_angle + 30:
            raise SoilError(
                f"blade_friction_angle = {self.blade_friction_angle}: must stay well "
                f"below friction_angle + 30 ({self.friction_angle + 30})"
            )
        n_factors(self)

    @property
    def physical(self) -> bool:
        """True for ``soil: physical`` (with or without a preset)."""
        return parse_soil(self.soil)[0] == "physical"

    def resolved(self) -> SoilParams:
        """These parameters with ``soil``'s preset and overrides applied.

        ``physical:PRESET,KEY=VALUE``: the preset's values replace these, then each
        ``KEY=VALUE`` replaces its parameter. The result's ``soil`` is the spec itself, so
        resolving twice changes nothing.
        """
        mode, preset, overrides = parse_soil(self.soil)
        if mode != "physical":
            return self
        values = {f.name: getattr(self, f.name) for f in fields(self)}
        values.update(PRESETS[preset].values)
        values.update(_typed_overrides(overrides, self.soil))
        try:
            return validate(SoilParams, values, node="soil")
        except ParameterError as e:
            raise SoilError(f"soil = {self.soil!r}: {e}") from None


# --- soil specs and presets -------------------------------------------------------------

_DEFAULTS = defaults(SoilParams)
_FIELDS = frozenset(_DEFAULTS) - {"soil"}


@dataclass(frozen=True)
class Preset:
    """A named world of soil and robot (``soil_presets.yaml``): values and their sources."""

    name: str
    title: str
    values: dict
    sources: dict


def _load_presets() -> dict[str, Preset]:
    """The presets of ``soil_presets.yaml`` beside this module (checked against the fields)."""
    path = Path(__file__).with_name("soil_presets.yaml")
    data = yaml.safe_load(path.read_text())
    names = {f.name for f in fields(SoilParams)} - {"soil"}
    out = {}
    for name, body in data["presets"].items():
        values, sources = {}, {}
        for key, entry in body.get("parameters", {}).items():
            if key not in names:
                raise SoilError(f"{path.name}: preset {name}: unknown parameter {key!r}")
            values[key] = entry["value"]
            sources[key] = entry["source"]
        out[name] = Preset(name, body["title"], values, sources)
    return out


def parse_soil(spec: str) -> tuple[str, str, list[tuple[str, str]]]:
    """``(mode, preset, overrides)`` of a soil spec (``soil`` of :class:`SoilParams`).

    ``grid``; ``physical`` (the preset ``grid``: calibrated to the grid's capacities);
    ``physical:PRESET``; either followed by ``,KEY=VALUE`` pairs naming parameters of
    :class:`SoilParams` (``physical:dome,repose=false``).

    Raises:
        SoilError: Naming the part of the spec that is not a soil.
    """
    if not isinstance(spec, str):
        raise SoilError(f"soil = {spec!r}: expected a string such as 'physical:dome'")
    head, *pairs = spec.split(",")
    mode, _, preset = head.partition(":")
    if mode not in SOIL_MODES:
        raise SoilError(f"soil = {spec!r}: {mode!r} is not one of {', '.join(SOIL_MODES)}")
    if mode == "grid":
        if preset or pairs:
            raise SoilError(f"soil = {spec!r}: the grid soil takes no preset or parameters")
        return mode, "", []
    preset = preset or "grid"
    if preset not in PRESETS:
        raise SoilError(f"soil = {spec!r}: unknown preset {preset!r} (one of {', '.join(PRESETS)})")
    overrides = []
    for pair in pairs:
        key, eq, value = pair.partition("=")
        key = key.strip()
        if not eq or key in ("", "soil") or key not in _FIELDS:
            raise SoilError(f"soil = {spec!r}: {pair!r} is not KEY=VALUE with a soil parameter")
        overrides.append((key, value.strip()))
    return mode, preset, overrides


def _typed_overrides(pairs: list[tuple[str, str]], spec: str) -> dict:
    """The ``KEY=VALUE`` overrides of a spec as the fields' types, each checked."""
    out = {}
    for key, text in pairs:
        kind = type(_DEFAULTS[key])
        try:
            if kind is bool:
                if text.lower() not in ("true", "false"):
                    raise ValueError(text)
                value = text.lower() == "true"
            else:
                value = kind(text)
        except ValueError:
            raise SoilError(f"soil = {spec!r}: {key} = {text!r} is not a {kind.__name__}") from None
        out[key] = value
    return out


PRESETS: dict[str, Preset] = _load_presets()
"""The named worlds: ``grid`` (calibrated to the grid's capacities), ``dome``, ``lunar``."""


def check_soil(spec: str) -> str:
    """``spec`` when it names a soil (:func:`parse_soil`, presets and values checked).

    Raises:
        SoilError: Naming what is wrong.
    """
    SoilParams(soil=spec).resolved()
    return spec


def soil_arg(text: str) -> str:
    """An ``argparse`` type for ``--soil``: :func:`check_soil` with argparse's error."""
    try:
        return check_soil(text)
    except SoilError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


soil_arg.__name__ = "soil"


@dataclass(frozen=True)
class Site:
    """The site's scale as the soil model needs it (from the blueprint)."""

    rows: int
    cols: int
    cell: float  # m per cell
    unit: float  # m per soil unit


# --- earth-moving model ------------------------------------------------------------------


def n_factors(params: SoilParams) -> tuple[float, float, float, float]:
    """McKyes's ``(N_gamma, N_c, N_q, beta)`` for the blade and soil of ``params``.

    ``beta`` is the failure plane angle from the horizontal that minimises ``N_gamma``
    (McKyes 1985: the soil fails along the plane of least resistance), searched on a
    0.1-degree grid.

    Raises:
        SoilError: When no failure plane gives a finite, positive resistance.
    """
    alpha = math.radians(params.rake_angle)
    phi = math.radians(params.friction_angle)
    delta = math.radians(params.blade_friction_angle)
    best = None
    for tenth in range(10, 900):
        beta = math.radians(tenth / 10)
        if beta + phi >= math.pi / 2 + math.pi / 2:
            break
        denominator = math.cos(alpha + delta) + math.sin(alpha + delta) / math.tan(beta + phi)
        if denominator <= 1e-9:
            continue
        cot_a, cot_b = 1 / math.tan(alpha), 1 / math.tan(beta)
        n_gamma = (cot_a + cot_b) / (2 * denominator)
        if n_gamma > 0 and (best is None or n_gamma < best[0]):
            n_c = (1 + cot_b / math.tan(beta + phi)) / denominator
            n_q = (cot_a + cot_b) / denominator
            best = (n_gamma, n_c, n_q, beta)
    if best is None:
        raise SoilError(
            f"rake_angle = {params.rake_angle}, friction_angle = {params.friction_angle}, "
            f"blade_friction_angle = {params.blade_friction_angle}: no failure plane"
        )
    return best


@dataclass(frozen=True)
class Physics:
    """Everything :func:`blade_resistance` and the stall test need, in SI units.

    Attributes:
        gamma: Soil unit weight, N/m^3.
        n_gamma, n_c, n_q: McKyes's factors.
        wedge: Failure wedge length per metre of soil depth (``cot alpha + cot beta``).
        drag: The drag prism's friction on the ground (``tan(friction_angle)``).
        motor: Motor force without and with throttle-up, N (calibrated).
        mass: Robot mass, kg (from the traction margin).
    """

    gamma: float
    cohesion: float
    n_gamma: float
    n_c: float
    n_q: float
    wedge: float
    drag: float
    wheel_friction: float
    gravity: float
    motor: tuple[float, float]
    mass: float
    full_scale: float = 0.0
    blade_limit: float = 0.0
    wheels: Terrain | None = None

    def traction(self) -> float:
        """The most push the wheels give, N.

        Terramechanics: the thrust at full slip less the rolling resistance; Coulomb: the
        friction of the robot's weight.
        """
        if self.wheels is not None:
            return self.wheels.thrust(1.0) - self.wheels.rolling
        return self.wheel_friction * self.mass * self.gravity

    def available(self, throttle: bool) -> float:
        """Push the robot gives: its motor force, at most what its wheels' traction gives."""
        return min(self.motor[int(throttle)], self.traction())

    def load_scale(self) -> float:
        """The force L1 reads as a full blade, N."""
        return self.full_scale or self.motor[1]

    def speed_factor(self, demand: float, blade: float, throttle: bool) -> float:
        """Share of the commanded speed the robot makes against ``demand`` N (0: it stalls).

        ``blade``: the part of the demand on the blade (over ``blade_limit`` it stalls).
        Coulomb wheels: all or nothing. Terramechanics: the wheels slip until their thrust
        (Janosi-Hanamoto) meets the demand plus the rolling resistance; the robot advances
        at ``1 - slip`` of its wheel speed, and stalls where no slip gives enough thrust or
        the motors cannot give it.
        """
        if self.blade_limit and blade > self.blade_limit:
            return 0.0
        if demand > self.motor[int(throttle)]:
            return 0.0
        if self.wheels is None:
            return 1.0 if demand <= self.available(throttle) else 0.0
        slip = self.wheels.slip_for(demand + self.wheels.rolling)
        return 0.0 if slip is None else 1.0 - slip


@dataclass(frozen=True)
class Terrain:
    """The running gear on the soil: Bekker sinkage and rolling, Janosi-Hanamoto thrust.

    The forms of J. Y. Wong, *Theory of Ground Vehicles* (ch. 2), which Project Chrono's
    SCM terrain also uses. Two sides, each a ``b`` x ``l`` contact, carry the weight.

    Attributes:
        weight: The robot's weight, N.
        sinkage: Static sinkage ``z = (p / (k_c / b + k_phi))^(1/n)``, m, with ``p`` the
            ground pressure.
        rolling: Compaction resistance ``2 b (k_c / b + k_phi) z^(n+1) / (n + 1)``, N.
        shear_max: The largest thrust ``2 b l c + W tan(phi)``, N.
        ratio: ``l / K``: contact length over the shear deformation modulus.
    """

    weight: float
    sinkage: float
    rolling: float
    shear_max: float
    ratio: float

    @classmethod
    def of(cls, params: SoilParams, mass: float) -> Terrain:
        """The running gear of a robot of ``mass`` kg on the soil of ``params``."""
        b, l = params.contact_width, params.contact_length
        weight = mass * params.gravity
        modulus = params.bekker_kc / b + params.bekker_kphi
        z = (weight / (2 * b * l) / modulus) ** (1 / params.bekker_n)
        rolling = 2 * b * modulus * z ** (params.bekker_n + 1) / (params.bekker_n + 1)
        phi = math.radians(params.shear_friction_angle)
        shear = 2 * b * l * params.shear_cohesion + weight * math.tan(phi)
        return cls(weight, z, rolling, shear, l / params.janosi_k)

    def thrust(self, slip: float) -> float:
        """Thrust at ``slip`` (0-1): ``H_max [1 - K / (s l) (1 - exp(-s l / K))]``, N."""
        x = slip * self.ratio
        if x < 1e-9:
            return 0.0
        return self.shear_max * (1 - (1 - math.exp(-x)) / x)

    def slip_for(self, force: float) -> float | None:
        """The slip whose thrust is ``force`` (bisection to 1e-6), or ``None`` above 100 %."""
        if force <= 0:
            return 0.0
        if force > self.thrust(1.0):
            return None
        low, high = 0.0, 1.0
        while high - low > 1e-6:
            mid = (low + high) / 2
            if self.thrust(mid) < force:
                low = mid
            else:
                high = mid
        return high


def mckyes_force(
    depth: float, surcharge_volume: float, width: float, length: float, physics: Physics
) -> float:
    """McKyes's blade force (N) for a ``depth`` m cut by a ``width`` m blade.

    ``surcharge_volume`` (m^3): soil lying on the failure wedge, spread over ``width`` x
    ``length`` (the wedge's length on the surface) as the surcharge ``q``.
    """
    if depth <= 0.0:
        return 0.0
    q = physics.gamma * max(surcharge_volume, 0.0) / (width * length) if length > 0 else 0.0
    p = physics
    return width * (
        p.gamma * depth * depth * p.n_gamma + p.cohesion * depth * p.n_c + q * depth * p.n_q
    )


@dataclass(frozen=True)
class BladeLoad:
    """What a blade meets (:meth:`Soil.load`), SI units.

    Attributes:
        depth: Firm ground above the edge just ahead of it, m (McKyes's cutting depth).
        over: Loose soil on the failure wedge, m^3 (the surcharge).
        beyond: Loose soil past the wedge within ``pile_reach``, m^3 (the drag prism).
    """

    depth: float
    over: float
    beyond: float


def blade_force(load: BladeLoad, width: float, physics: Physics) -> float:
    """The blade's horizontal force (N): cutting plus dragging the prism.

    The cut: McKyes's equation, depth the firm ground cut, surcharge the loose soil on its
    failure wedge (``depth * wedge`` long). The drag: the loose soil beyond the wedge slides
    over the ground on its own internal friction (its weight times ``tan(friction_angle)``:
    the drag prism's resistance of the dozing literature, e.g. Zelenin, Balovnev and Kerov,
    *Machines for Moving the Earth*, 1985).
    """
    cutting = mckyes_force(load.depth, load.over, width, load.depth * physics.wedge, physics)
    return cutting + physics.drag * physics.gamma * load.beyond


# --- kernels -------------------------------------------------------------------------------


@nb.njit(cache=True)
def cell_sums(fine, s, out):
    """``out[r, c]``: the sum of cell ``(r, c)``'s ``s`` x ``s`` sub-cells (quanta)."""
    rows, cols = out.shape
    for r in range(rows):
        for c in range(cols):
            total = 0
            for i in range(s):
                for j in range(s):
                    total += fine[r * s + i, c * s + j]
            out[r, c] = total


@nb.njit(cache=True)
def round_heights(sums, per_cell, out):
    """Cell heights in whole units: the sub-cell mean rounded, halves up."""
    rows, cols = sums.shape
    for r in range(rows):
        for c in range(cols):
            out[r, c] = (2 * sums[r, c] + per_cell) // (2 * per_cell)


_SQUARE = (
    (0.0, 1.0, 0.0),
    (math.pi / 2, 0.0, 1.0),
    (-math.pi / 2, 0.0, -1.0),
    (math.pi, -1.0, 0.0),
)
"""The square headings and their exact cosines and sines (``math.cos(pi / 2)`` is 6e-17)."""


@nb.njit(cache=True, inline="always")
def cos_sin(yaw):
    """``(cos(yaw), sin(yaw))``; exactly 0 and +-1 for a heading square to the grid.

    Every robot of the offline world and most of ``dynamics``' stand square; their kernels
    call this several times a sub-step. With exact values a sub-cell's ``u`` in such a
    robot's frame depends on its column only (or its row only), so a rectangle's sub-cells
    are a window of whole rows and columns (:func:`_band`).
    """
    for square, c, s in _SQUARE:
        if yaw == square:
            return c, s
    return math.cos(yaw), math.sin(yaw)


_SPARE = 1e-6
"""Sub-cells :func:`_rect` reaches beyond a rectangle's bounding box, against rounding."""


@nb.njit(cache=True, inline="always")
def _rect(x, y, cy, sy, u0, u1, v0, v1, sub, rows, cols):
    """Row and column bounds ``(i0, i1, j0, j1)`` of the sub-cells a robot's rectangle covers.

    The rectangle: ``u0 <= u <= u1``, ``v0 <= v <= v1`` in the robot's frame (:func:`_local`);
    the bounds: the sub-cells whose centres lie in its bounding box on the field (with a
    millionth of a sub-cell to spare against rounding): a kernel that tests each centre
    against the rectangle visits only these, in the same order as over a larger window, so
    its result is the same. For a robot square to the grid (every robot of the offline
    world) that is the rectangle's own sub-cells.
    """
    x0 = x1 = x + u0 * cy - v0 * sy
    y0 = y1 = y + u0 * sy + v0 * cy
    for u, v in ((u0, v1), (u1, v0), (u1, v1)):
        px = x + u * cy - v * sy
        py = y + u * sy + v * cy
        x0 = min(x0, px)
        x1 = max(x1, px)
        y0 = min(y0, py)
        y1 = max(y1, py)
    # sub-cell i's centre is (i + 0.5) * sub
    # clipped so that 0 <= i0 <= i1 <= rows (likewise the columns): a rectangle wholly off
    # the field gives an empty window, never a negative end (a slice would wrap)
    i0 = min(max(int(math.ceil(y0 / sub - 0.5 - _SPARE)), 0), rows)
    i1 = max(min(int(math.floor(y1 / sub - 0.5 + _SPARE)) + 1, rows), i0)
    j0 = min(max(int(math.ceil(x0 / sub - 0.5 - _SPARE)), 0), cols)
    j1 = max(min(int(math.floor(x1 / sub - 0.5 + _SPARE)) + 1, cols), j0)
    return i0, i1, j0, j1


@nb.njit(cache=True, inline="always")
def _local(i, j, sub, x, y, cy, sy):
    """Sub-cell ``(i, j)``'s centre ``(u, v)`` in the frame of a robot at ``(x, y)``.

    ``u`` ahead along its heading (``cy, sy``: cosine and sine of its yaw), ``v`` to its left.
    """
    dx = (j + 0.5) * sub - x
    dy = (i + 0.5) * sub - y
    return dx * cy + dy * sy, -dx * sy + dy * cy


@nb.njit(cache=True, inline="always")
def _on(k, origin, sign, sub, lo, hi, open_lo):
    """Whether index k's coordinate ``((k + 0.5) * sub - origin) * sign`` lies in ``[lo, hi)``.

    The same float :func:`_local` computes along an axis of a square heading (``sign``: its
    +-1 cosine or sine; the other term is an exact zero). ``open_lo``: ``(lo, hi)``.
    """
    w = ((k + 0.5) * sub - origin) * sign
    return (w > lo if open_lo else w >= lo) and w < hi


@nb.njit(cache=True, inline="always")
def _span(count, origin, sign, sub, lo, hi, open_lo):
    """The indices ``[a, b)`` of ``[0, count)`` that are :func:`_on` (a range: monotone).

    Solved for the bounds, then each bound is moved while the exact test says so (the
    solution is at most one index off), so the range is exactly the indices the test takes.
    """
    if sign > 0.0:
        a = math.ceil((origin + lo) / sub - 0.5)
        b = math.ceil((origin + hi) / sub - 0.5)
    else:
        a = math.floor((origin - hi) / sub - 0.5) + 1
        b = math.floor((origin - lo) / sub - 0.5) + 1
    a = min(max(a, 0), count)
    b = min(max(b, a), count)
    while a > 0 and _on(a - 1, origin, sign, sub, lo, hi, open_lo):
        a -= 1
    while a < b and not _on(a, origin, sign, sub, lo, hi, open_lo):
        a += 1
    while b < count and _on(b, origin, sign, sub, lo, hi, open_lo):
        b += 1
    while b > a and not _on(b - 1, origin, sign, sub, lo, hi, open_lo):
        b -= 1
    return a, b


@nb.njit(cache=True, inline="always")
def _axes(x, y, cy, sy, rows, cols):
    """A square heading's axes: ``(along, nu, u_at, u_sign, nv, v_at, v_sign)``.

    ``along``: ``u`` runs along the columns (``sy == 0``: ``u = dx * cy``, ``v = dy * cy``),
    else along the rows (``u = dy * sy``, ``v = dx * -sy``); each axis's index count,
    origin and sign as :func:`_span` takes them.
    """
    if sy == 0.0:
        return True, cols, x, cy, rows, y, cy
    return False, rows, y, sy, cols, x, -sy


@nb.njit(cache=True, inline="always")
def _band(x, y, cy, sy, u0, u1, half_width, sub, rows, cols):
    """``(i0, i1, j0, j1, every)``: the window of the sub-cells ``u0 <= u < u1, |v| < half_width``.

    ``every``: each sub-cell of the window qualifies (a square heading: exactly the
    sub-cells :func:`_local`'s test selects, as whole rows and columns); otherwise
    (:func:`_rect`'s window) each must be tested.
    """
    if sy == 0.0 or cy == 0.0:
        along, nu, u_at, u_sign, nv, v_at, v_sign = _axes(x, y, cy, sy, rows, cols)
        a0, a1 = _span(nu, u_at, u_sign, sub, u0, u1, False)
        b0, b1 = _span(nv, v_at, v_sign, sub, -half_width, half_width, True)
        if along:
            return b0, b1, a0, a1, True
        return a0, a1, b0, b1, True
    i0, i1, j0, j1 = _rect(x, y, cy, sy, u0, u1, -half_width, half_width, sub, rows, cols)
    return i0, i1, j0, j1, False


@nb.njit(cache=True, inline="always")
def body_window(x, y, yaw, sub, half_length, half_width, wing, rows, cols):
    """The window ``(i0, i1, j0, j1)`` :func:`stamp_body` visits for a body at ``(x, y, yaw)``."""
    cy, sy = cos_sin(yaw)
    side = half_width + sub
    return _rect(x, y, cy, sy, -half_length, half_length + wing, -side, side, sub, rows, cols)


@nb.njit(cache=True, inline="always")
def _fill(mask, along, a0, a1, b0, b1):
    """Mark ``u`` indices ``[a0, a1)`` by ``v`` indices ``[b0, b1)`` (``along``: u on columns)."""
    if along:
        mask[b0:b1, a0:a1] = True
    else:
        mask[a0:a1, b0:b1] = True


@nb.njit(cache=True, inline="always")
def stamp_body(mask, x, y, yaw, sub, half_length, half_width, wings_on, wing):
    """Mark the sub-cells under one body (and, ``wings_on``, its blade's end plates).

    :func:`body_mask` stamps each active robot with it.
    """
    rows, cols = mask.shape
    cy, sy = cos_sin(yaw)
    ahead = half_length + wing
    side = half_width + sub
    if sy == 0.0 or cy == 0.0:  # square: whole rows and columns (see _band)
        along, nu, u_at, u_sign, nv, v_at, v_sign = _axes(x, y, cy, sy, rows, cols)
        a0, a1 = _span(nu, u_at, u_sign, sub, -half_length, half_length, True)
        b0, b1 = _span(nv, v_at, v_sign, sub, -half_width, half_width, True)
        _fill(mask, along, a0, a1, b0, b1)
        if wings_on:
            a0, a1 = _span(nu, u_at, u_sign, sub, half_length, ahead, False)
            for sign in (v_sign, -v_sign):  # each side: half_width <= |v| < side
                b0, b1 = _span(nv, v_at, sign, sub, half_width, side, False)
                _fill(mask, along, a0, a1, b0, b1)
        return
    i0, i1, j0, j1 = _rect(x, y, cy, sy, -half_length, ahead, -side, side, sub, rows, cols)
    for i in range(i0, i1):
        for j in range(j0, j1):
            u, v = _local(i, j, sub, x, y, cy, sy)
            if abs(u) < half_length and abs(v) < half_width:
                mask[i, j] = True
            elif (
                wings_on
                and half_length <= u < half_length + wing
                and half_width <= abs(v) < half_width + sub
            ):
                mask[i, j] = True


@nb.njit(cache=True)
def body_mask(mask, bodies, active, sub, half_length, half_width, wings=None, wing=0.0):
    """Mark the sub-cells whose centres lie under an active robot's body rectangle.

    With ``wings[k]`` (robot k's blade is down) also its blade's end plates: the lanes one
    sub-cell wide just beyond the blade's ends, ``wing`` m ahead of the edge.
    """
    mask[:] = False
    for k in range(bodies.shape[0]):
        if not active[k]:
            continue
        wings_on = False
        if wings is not None:
            wings_on = bool(wings[k])
        stamp_body(
            mask, bodies[k, 0], bodies[k, 1], bodies[k, 2], sub, half_length, half_width,
            wings_on, wing,
        )  # fmt: skip


@nb.njit(cache=True, inline="always")
def _move(fine, loose, i, j, ti, tj, amount):
    """Move ``amount`` quanta from the top of sub-cell ``(i, j)`` onto ``(ti, tj)``.

    The top of a sub-cell is its loose soil first (``loose`` counts the quanta of each
    sub-cell a blade, a slope or a wheel has moved, lying over the firm ground the site
    started with); what arrives is loose. ``0 <= loose <= fine`` holds where it held.
    Both sub-cells lie on the field (every caller checks), so it reads and writes through
    :func:`on_field` and :func:`set_on_field`.
    """
    set_on_field(fine, i, j, on_field(fine, i, j) - amount)
    set_on_field(fine, ti, tj, on_field(fine, ti, tj) + amount)
    held = on_field(loose, i, j)
    set_on_field(loose, i, j, held - (amount if amount < held else held))
    set_on_field(loose, ti, tj, on_field(loose, ti, tj) + amount)


@nb.njit(cache=True)
def relax(fine, loose, blocked, max_diff, passes):
    """Settle slopes steeper than ``max_diff`` quanta per sub-cell; returns the quanta moved.

    Each pass sweeps the field (forwards, then backwards on the next pass) and, for each
    pair of 4-neighbours neither of which is ``blocked``, moves half the excess over
    ``max_diff`` (rounded up) from the higher to the lower (:func:`_move`: it arrives
    loose). Whole quanta move between two sub-cells, so the sum is unchanged.
    """
    rows, cols = fine.shape
    moved = 0
    for p in range(passes):
        forwards = p % 2 == 0
        for a in range(rows):
            i = a if forwards else rows - 1 - a
            for b in range(cols):
                j = b if forwards else cols - 1 - b
                if blocked[i, j]:
                    continue
                for n in range(2):
                    ni = i + (1 if n == 0 else 0)
                    nj = j + (1 if n == 1 else 0)
                    if not forwards:
                        ni = i - (1 if n == 0 else 0)
                        nj = j - (1 if n == 1 else 0)
                    if ni < 0 or nj < 0 or ni >= rows or nj >= cols or blocked[ni, nj]:
                        continue
                    diff = fine[i, j] - fine[ni, nj]
                    if diff > max_diff:
                        t = (diff - max_diff + 1) // 2
                        _move(fine, loose, i, j, ni, nj, t)
                        moved += t
                    elif -diff > max_diff:
                        t = (-diff - max_diff + 1) // 2
                        _move(fine, loose, ni, nj, i, j, t)
                        moved += t
    return moved


@nb.njit(cache=True, inline="always")
def _push(stack, queued, top, i, j, window):
    """Queue sub-cell ``(i, j)`` on ``stack`` unless it is queued already; the new top.

    An entry holds ``i << 32 | j`` (shifts, not a division by the columns, to read it back).
    ``window`` (``i0, j0, j1, a, b``): the sub-cells of rows ``i0..a`` and columns
    ``[j0, j1)`` that come before ``(a, b)`` in row-major order count as queued
    (:func:`relax_local`).
    """
    if on_field(queued, i, j):
        return top
    i0, j0, j1, a, b = window
    if i0 <= i and j0 <= j < j1 and (i < a or (i == a and j < b)):
        return top
    set_on_field(queued, i, j, True)
    stack[top] = (i << 32) | j
    return top + 1


@nb.njit(cache=True, inline="always")
def _settle_pair(fine, loose, blocked, max_diff, i, j, ni, nj):
    """One step of :func:`relax_local`: sub-cell ``(i, j)`` against its neighbour ``(ni, nj)``.

    Returns the quanta moved (0: none; a move is at least one quantum). ``blocked[ni, nj]``
    is read only where the slope is too steep (it decides nothing elsewhere).
    """
    diff = on_field(fine, i, j) - on_field(fine, ni, nj)
    if diff > max_diff:
        if on_field(blocked, ni, nj):
            return 0
        t = (diff - max_diff + 1) // 2
        _move(fine, loose, i, j, ni, nj, t)
        return t
    if -diff > max_diff:
        if on_field(blocked, ni, nj):
            return 0
        t = (-diff - max_diff + 1) // 2
        _move(fine, loose, ni, nj, i, j, t)
        return t
    return 0


@nb.njit(cache=True, inline="always")
def on_field(a, i, j):
    """``a[i, j]`` where ``0 <= i, j`` is known (the caller checked the bounds).

    Read through unsigned indices, numba adds no wraparound for negative ones: the hot
    loops lose a test and a select per read, and short rows load as plain vectors (the
    rounded heights' refresh had gathered each one). The value is ``a[i, j]``'s.
    """
    return a[np.uint64(i), np.uint64(j)]


@nb.njit(cache=True, inline="always")
def set_on_field(a, i, j, value):
    """``a[i, j] = value`` where ``0 <= i, j`` is known (:func:`on_field`'s write)."""
    a[np.uint64(i), np.uint64(j)] = value


@nb.njit(cache=True, inline="always")
def _steep(fine, blocked, max_diff, i, j, ni, nj):
    """Whether :func:`_settle_pair` would move soil between ``(i, j)`` and ``(ni, nj)``."""
    return abs(on_field(fine, i, j) - on_field(fine, ni, nj)) > max_diff and not on_field(
        blocked, ni, nj
    )


@nb.njit(cache=True, inline="always")
def _steep_at(fine, blocked, max_diff, i, j):
    """Whether sub-cell ``(i, j)`` (not ``blocked``) would move soil to or from a neighbour."""
    rows, cols = fine.shape
    return (
        (i + 1 < rows and _steep(fine, blocked, max_diff, i, j, i + 1, j))
        or (i >= 1 and _steep(fine, blocked, max_diff, i, j, i - 1, j))
        or (j + 1 < cols and _steep(fine, blocked, max_diff, i, j, i, j + 1))
        or (j >= 1 and _steep(fine, blocked, max_diff, i, j, i, j - 1))
    )


@nb.njit(cache=True, _nrt=False)
def relax_local(fine, loose, blocked, max_diff, i0, i1, j0, j1, stack, queued, touched):
    """Settle every slope steeper than ``max_diff`` that sub-cells ``[i0:i1, j0:j1]`` start.

    A worklist avalanche: each queued sub-cell (never a ``blocked`` one: a move involves
    none) is compared with its 4-neighbours that are not ``blocked``; where the slope
    exceeds ``max_diff``, half the excess (rounded up) moves from the higher to the lower
    (:func:`_move`) and both are queued again, wherever they lie. It ends where no slope
    exceeds ``max_diff`` around any sub-cell it touched (each move lowers the sum of
    squared heights when ``max_diff >= 1``), at a cost in proportion to the avalanche, not
    the field. ``stack`` (``int64``, one slot per sub-cell) and ``queued`` (``bool`` like
    ``fine``, all False) are scratch; ``queued`` is all False again on return. ``touched``
    (``int64 [4]``: first row, last row, first column, last column) grows to cover every
    sub-cell that changed. Returns the quanta moved.

    The window's sub-cells start on the worklist in row-major order (the last on top).
    They are not written to it: the worklist takes them from the last to the first, each
    followed by everything its moves queue (a stack), so the window's sub-cells before the
    one taken count as queued (:func:`_push`), and a sub-cell with no slope to settle,
    which would change nothing, is passed over with one test of its four neighbours. Most
    are: a robot's sub-step checks some 90 and moves soil at one or two.

    The window must lie on the field (``0 <= i0 <= i1 <= rows``, likewise the columns;
    callers clip it): the walk reads and writes through :func:`on_field` and
    :func:`set_on_field`, which do not wrap negative indices.
    """
    rows, cols = fine.shape
    moved = 0
    low = 0xFFFFFFFF
    r0 = touched[0]
    r1 = touched[1]
    c0 = touched[2]
    c1 = touched[3]
    for a in range(i1 - 1, i0 - 1, -1):
        for b in range(j1 - 1, j0 - 1, -1):
            if on_field(blocked, a, b) or not _steep_at(fine, blocked, max_diff, a, b):
                continue
            window = (i0, j0, j1, a, b)
            set_on_field(queued, a, b, True)
            stack[0] = (a << 32) | b
            top = 1
            while top > 0:
                top -= 1
                i = stack[top] >> 32
                j = stack[top] & low
                set_on_field(queued, i, j, False)
                # the neighbours in the order below, above, right, left
                if i + 1 < rows:
                    t = _settle_pair(fine, loose, blocked, max_diff, i, j, i + 1, j)
                    if t > 0:
                        moved += t
                        r0 = min(r0, i, i + 1)
                        r1 = max(r1, i, i + 1)
                        c0 = min(c0, j, j)
                        c1 = max(c1, j, j)
                        top = _push(stack, queued, top, i, j, window)
                        top = _push(stack, queued, top, i + 1, j, window)
                if i >= 1:
                    t = _settle_pair(fine, loose, blocked, max_diff, i, j, i - 1, j)
                    if t > 0:
                        moved += t
                        r0 = min(r0, i, i - 1)
                        r1 = max(r1, i, i - 1)
                        c0 = min(c0, j, j)
                        c1 = max(c1, j, j)
                        top = _push(stack, queued, top, i, j, window)
                        top = _push(stack, queued, top, i - 1, j, window)
                if j + 1 < cols:
                    t = _settle_pair(fine, loose, blocked, max_diff, i, j, i, j + 1)
                    if t > 0:
                        moved += t
                        r0 = min(r0, i, i)
                        r1 = max(r1, i, i)
                        c0 = min(c0, j, j)
                        c1 = max(c1, j, j + 1)
                        top = _push(stack, queued, top, i, j, window)
                        top = _push(stack, queued, top, i, j + 1, window)
                if j >= 1:
                    t = _settle_pair(fine, loose, blocked, max_diff, i, j, i, j - 1)
                    if t > 0:
                        moved += t
                        r0 = min(r0, i, i)
                        r1 = max(r1, i, i)
                        c0 = min(c0, j, j - 1)
                        c1 = max(c1, j, j)
                        top = _push(stack, queued, top, i, j, window)
                        top = _push(stack, queued, top, i, j - 1, window)
    touched[0] = r0
    touched[1] = r1
    touched[2] = c0
    touched[3] = c1
    return moved


@nb.njit(cache=True, inline="always")
def _index(x, y, sub, rows, cols):
    """Sub-cell ``(i, j)`` holding point ``(x, y)``, or ``(-1, -1)`` off the field."""
    i = int(math.floor(y / sub))
    j = int(math.floor(x / sub))
    if i < 0 or j < 0 or i >= rows or j >= cols:
        return -1, -1
    return i, j


@nb.njit(cache=True, _nrt=False)
def band_ground(fine, x, y, yaw, sub, near, far, half_width):
    """Summed height (quanta) and count of the sub-cells in a band of a robot's body.

    The band: centres between ``near`` and ``far`` m ahead of ``(x, y)`` along ``yaw``
    and less than ``half_width`` m to either side. ``n`` is 0 when none lies on the field.
    """
    rows, cols = fine.shape
    cy, sy = cos_sin(yaw)
    i0, i1, j0, j1, every = _band(x, y, cy, sy, near, far, half_width, sub, rows, cols)
    total = 0
    n = 0
    if every:
        for i in range(i0, i1):
            total += fine[i, j0:j1].sum()
        return total, (i1 - i0) * (j1 - j0)
    for i in range(i0, i1):
        for j in range(j0, j1):
            u, v = _local(i, j, sub, x, y, cy, sy)
            if abs(v) < half_width and near <= u < far:
                total += fine[i, j]
                n += 1
    return total, n


@nb.njit(cache=True, _nrt=False)
def dig_wheels(fine, loose, x, y, yaw, sub, length, half_width, take):
    """Slipping wheels carry soil back: ``take`` quanta from each sub-cell under the rear half.

    The sub-cells whose centres lie between ``length`` m behind ``(x, y)`` and ``(x, y)``
    along ``yaw`` and within ``half_width`` to either side each give ``take`` quanta to the
    sub-cell one body length plus one sub-cell behind them (off the field: they keep it).
    Whole quanta move between two sub-cells, so the sum is unchanged. Returns the quanta
    moved.
    """
    rows, cols = fine.shape
    cy, sy = cos_sin(yaw)
    i0, i1, j0, j1 = _rect(x, y, cy, sy, -length, 0.0, -half_width, half_width, sub, rows, cols)
    moved = 0
    for i in range(i0, i1):
        for j in range(j0, j1):
            u, v = _local(i, j, sub, x, y, cy, sy)
            if abs(v) >= half_width or u >= 0.0 or u < -length:
                continue
            px = (j + 0.5) * sub - (u + length + sub) * cy
            py = (i + 0.5) * sub - (u + length + sub) * sy
            ti, tj = _index(px, py, sub, rows, cols)
            if ti < 0 or (ti == i and tj == j):
                continue
            _move(fine, loose, i, j, ti, tj, take)
            moved += take
    return moved


@nb.njit(cache=True, _nrt=False)
def volume_above(fine, x, y, yaw, sub, front, half_width, reach, edge):
    """Soil above ``edge`` (quanta, summed over sub-cells) up to ``reach`` m ahead of a blade.

    The sub-cells whose centres lie between the blade's edge (``front`` m ahead of ``(x,
    y)`` along ``yaw``) and ``reach`` m beyond it, within ``half_width`` to either side.
    """
    rows, cols = fine.shape
    cy, sy = cos_sin(yaw)
    i0, i1, j0, j1, every = _band(x, y, cy, sy, front, front + reach, half_width, sub, rows, cols)
    volume = 0
    for i in range(i0, i1):
        for j in range(j0, j1):
            if not every:
                u, v = _local(i, j, sub, x, y, cy, sy)
                if abs(v) >= half_width or u < front or u >= front + reach:
                    continue
            above = on_field(fine, i, j) - edge
            if above > 0:
                volume += above
    return volume


@nb.njit(cache=True, inline="always")
def firm_above(fine, loose, edge):
    """Quanta of a sub-cell's firm ground (``fine - loose``) above a blade's ``edge``.

    What the blade cuts there (:func:`blade_load`).
    """
    firm = fine - loose - edge
    return firm if firm > 0 else 0


@nb.njit(cache=True, inline="always")
def pile_above(fine, loose, edge):
    """Quanta of a sub-cell's loose soil above a blade's ``edge``.

    What the blade pushes there (:func:`blade_load`).
    """
    pile = fine - edge
    if pile <= 0:
        return 0
    return loose if pile > loose else pile


@nb.njit(cache=True, _nrt=False)
def blade_load(fine, loose, x, y, yaw, sub, front, half_width, reach, edge, wedge):
    """``(cut, over, beyond)``: what a blade at ``(x, y, yaw)``, edge at ``edge``, meets.

    ``cut``: the mean depth (quanta) of firm ground (``fine - loose``) above the edge in
    the sub-cells within one sub-cell ahead of it, the layer the blade cuts next.
    ``over``: loose soil above the edge (quanta, summed) on McKyes's failure wedge, the
    ``cut * wedge`` quanta-lengths ahead of the edge (``wedge``: the wedge's length per
    quantum of depth, m); ``beyond``: loose soil above the edge past the wedge and up to
    ``reach`` m ahead, the drag prism the blade pushes along the ground.
    """
    rows, cols = fine.shape
    cy, sy = cos_sin(yaw)
    i0, i1, j0, j1, every = _band(x, y, cy, sy, front, front + sub, half_width, sub, rows, cols)
    cut_total = 0
    cut_n = 0
    for i in range(i0, i1):
        for j in range(j0, j1):
            if not every:
                u, v = _local(i, j, sub, x, y, cy, sy)
                if abs(v) >= half_width or u < front or u >= front + sub:
                    continue
            cut_total += firm_above(on_field(fine, i, j), on_field(loose, i, j), edge)
            cut_n += 1
    depth = cut_total / cut_n if cut_n else 0.0
    length = depth * wedge
    far = length if length > reach else reach
    i0, i1, j0, j1, every = _band(x, y, cy, sy, front, front + far, half_width, sub, rows, cols)
    over = 0
    beyond = 0
    for i in range(i0, i1):
        for j in range(j0, j1):
            pile = pile_above(on_field(fine, i, j), on_field(loose, i, j), edge)
            if pile == 0:
                continue
            u, v = _local(i, j, sub, x, y, cy, sy)
            if not every and (abs(v) >= half_width or u < front or u >= front + far):
                continue
            if u < front + length:
                over += pile
            else:
                beyond += pile
    return depth, over, beyond


@nb.njit(cache=True, _nrt=False)
def cut(fine, loose, blocked, x, y, yaw, sub, front, half_width, edge, top, fill=True):
    """The blade at ``(x, y, yaw)`` levels the sub-cells just behind its edge to ``edge``.

    Soil above the edge goes to the sub-cell one sub-cell ahead (the pile); a sub-cell
    below it takes what the one ahead holds above the edge, up to the edge; soil ahead
    standing more than ``top`` quanta above the edge falls over the blade onto the sub-cell
    1.5 sub-cells behind the edge. A target off the field or under another robot's body
    (``blocked`` and not behind this blade) is left alone. Without ``fill`` a sub-cell
    below the edge stays as it is. Returns the quanta cut.
    """
    rows, cols = fine.shape
    cy, sy = cos_sin(yaw)
    i0, i1, j0, j1 = _rect(
        x, y, cy, sy, front - sub, front + sub, -half_width, half_width, sub, rows, cols
    )
    total = 0
    for i in range(i0, i1):
        for j in range(j0, j1):
            px = (j + 0.5) * sub
            py = (i + 0.5) * sub
            u, v = _local(i, j, sub, x, y, cy, sy)
            if abs(v) >= half_width:
                continue
            if front - sub <= u < front:
                ti, tj = _index(px + sub * cy, py + sub * sy, sub, rows, cols)
                if ti < 0 or (ti == i and tj == j) or blocked[ti, tj]:
                    continue
                excess = fine[i, j] - edge
                if excess > 0:
                    _move(fine, loose, i, j, ti, tj, excess)
                    total += excess
                elif excess < 0 and fill:
                    spare = fine[ti, tj] - edge
                    if spare > 0:
                        take = -excess if -excess < spare else spare
                        _move(fine, loose, ti, tj, i, j, take)
            elif front <= u < front + sub:
                over = fine[i, j] - edge - top
                if over > 0:
                    bi, bj = _index(px - 1.5 * sub * cy, py - 1.5 * sub * sy, sub, rows, cols)
                    if bi >= 0 and not (bi == i and bj == j):
                        _move(fine, loose, i, j, bi, bj, over)
    return total


# --- the soil ----------------------------------------------------------------------------


class Soil:
    """The fine height field of one world and its blade physics (see the module docstring).

    Args:
        heights: The grid's starting heights, soil units (each cell's sub-cells start level
            at its height).
        site: Rows, columns, cell size and unit height.
        params: Soil and blade parameters.

    Raises:
        SoilError: When the fine field would exceed :data:`MAX_FINE_CELLS` sub-cells or the
            parameters describe no soil.
    """

    def __init__(
        self,
        heights: np.ndarray,
        site: Site,
        params: SoilParams,
        physics: Physics | None = None,
        capacities: tuple[int, int] = (12, 24),
    ) -> None:
        params.check()
        s = params.subcells
        if site.rows * site.cols * s * s > MAX_FINE_CELLS:
            raise SoilError(
                f"subcells = {s}: a {site.rows} x {site.cols} site would need "
                f"{site.rows * site.cols * s * s} sub-cells (at most {MAX_FINE_CELLS})"
            )
        self.params = params
        self.site = site
        self.s = s
        self.q = params.quanta
        self.sub = site.cell / s
        heights = np.asarray(heights, dtype=np.int64)
        self.fine = np.repeat(np.repeat(heights * self.q, s, axis=0), s, axis=1)
        self.fine = np.ascontiguousarray(self.fine, dtype=np.int64)
        self.loose = np.zeros_like(self.fine)
        self.blocked = np.zeros(self.fine.shape, dtype=np.bool_)
        self.sums = np.zeros((site.rows, site.cols), dtype=np.int64)
        self.max_diff = int(
            math.tan(math.radians(params.repose_angle)) * self.sub / site.unit * self.q
        )
        self.top = int(params.blade_height / site.unit * self.q)
        self.physics = physics or calibrate(params, site.cell, site.unit, capacities)
        self.total = int(self.fine.sum())

    # --- measures ------------------------------------------------------------------------------

    def volume(self) -> int:
        """Total soil, quanta (constant over a trial)."""
        return int(self.fine.sum())

    def cell_means(self) -> np.ndarray:
        """Cell heights in soil units, the mean of each cell's sub-cells (float)."""
        cell_sums(self.fine, self.s, self.sums)
        return self.sums / float(self.s * self.s * self.q)

    def cell_heights(self, out: np.ndarray) -> None:
        """Write each cell's mean height rounded to a whole unit into ``out`` (int32)."""
        cell_sums(self.fine, self.s, self.sums)
        rounded = np.empty_like(self.sums)
        round_heights(self.sums, self.s * self.s * self.q, rounded)
        out[...] = rounded

    def fine_metres(self) -> np.ndarray:
        """The fine field in metres (what the synthetic laser sees)."""
        return self.fine * (self.site.unit / self.q)

    # --- the blade -----------------------------------------------------------------------------

    @property
    def front(self) -> float:
        """Distance from a robot's centre to its blade edge, m (the body's front)."""
        return self.site.cell

    @property
    def half_width(self) -> float:
        """Half the blade's width, m (the body's half width)."""
        return self.site.cell

    def ground(self, x: float, y: float, yaw: float) -> int:
        """The front axle's ground under a robot at ``(x, y, yaw)``, quanta.

        The mean of the rear half of the body's front row (the half the blade has not just
        cut); 0 where none of it lies on the field.
        """
        cell = self.site.cell
        total, n = band_ground(self.fine, x, y, yaw, self.sub, 0.0, cell / 2, self.half_width)
        return total // n if n else 0

    def resistance(self, x: float, y: float, yaw: float, edge: int) -> float:
        """The force (N) on the blade of a robot at ``(x, y, yaw)``, edge at ``edge``.

        McKyes's equation with the firm ground the blade cuts as its depth and the loose
        soil on the failure wedge as its surcharge, plus the drag of the loose soil beyond
        the wedge (:func:`blade_force`).
        """
        return blade_force(self.load(x, y, yaw, edge), 2 * self.half_width, self.physics)

    def load(self, x: float, y: float, yaw: float, edge: int) -> BladeLoad:
        """What the blade of a robot at ``(x, y, yaw)``, edge at ``edge``, cuts and pushes."""
        unit = self.site.unit / self.q
        depth, over, beyond = blade_load(
            self.fine,
            self.loose,
            x,
            y,
            yaw,
            self.sub,
            self.front,
            self.half_width,
            self.params.pile_reach * self.site.cell,
            edge,
            unit * self.physics.wedge,
        )
        volume = unit * self.sub * self.sub
        return BladeLoad(depth * unit, over * volume, beyond * volume)

    def held(self, x: float, y: float, yaw: float, edge: int) -> int:
        """Soil above ``edge`` ahead of a blade at ``(x, y, yaw)`` (quanta, over sub-cells).

        The physical ``V_blade``: what lies against the blade within ``pile_reach`` cells.
        """
        reach = self.params.pile_reach * self.site.cell
        return int(
            volume_above(self.fine, x, y, yaw, self.sub, self.front, self.half_width, reach, edge)
        )

    def relief(self, x: float, y: float, yaw: float, edge: int, limit: float) -> int:
        """How far (quanta) the edge must rise for the blade's force to be within ``limit``.

        Bisection on whole quanta up to 8 units above ``edge``: the smallest rise whose
        force is at most ``limit`` (the highest tried when none is).
        """
        if self.resistance(x, y, yaw, edge) <= limit:
            return 0
        low, high = 0, 8 * self.q
        while high - low > 1:
            mid = (low + high) // 2
            if self.resistance(x, y, yaw, edge + mid) <= limit:
                high = mid
            else:
                low = mid
        return high

    def cut(self, x: float, y: float, yaw: float, edge: int) -> int:
        """Level the sub-cells the blade just passed to ``edge``; returns the quanta cut."""
        return int(
            cut(
                self.fine,
                self.loose,
                self.blocked,
                x,
                y,
                yaw,
                self.sub,
                self.front,
                self.half_width,
                edge,
                self.top,
                self.params.fill,
            )
        )

    def settle(self, bodies: np.ndarray, active: np.ndarray, blades_down=None) -> int:
        """Mark the robots' bodies (and lowered blades' end plates), relax the field.

        Returns the quanta moved.
        """
        body_mask(
            self.blocked,
            bodies,
            active,
            self.sub,
            self.site.cell,
            self.site.cell,
            blades_down,
            self.params.end_plates * self.site.cell,
        )
        if not self.params.repose:
            return 0
        return int(
            relax(self.fine, self.loose, self.blocked, self.max_diff, self.params.relax_passes)
        )

    def heap(self, x: float, y: float, yaw: float, units: float) -> None:
        """Put ``units`` of soil against a blade at ``(x, y, yaw)``: the pile it holds.

        A prism across the blade's width whose face stands at the edge and whose top falls
        away at the angle of repose (the grid's picture of soil held against the blade, not
        yet slumped past the blade's ends): the calibration's pile, and the tests'.

        Raises:
            SoilError: When the blade's front is off the field.
        """
        rows, cols = self.fine.shape
        cy, sy = math.cos(yaw), math.sin(yaw)
        lanes = int(round(2 * self.half_width / self.sub))
        depth = 4 * self.s * 8
        cells = np.full((depth, lanes, 2), -1, dtype=np.int64)
        for m in range(depth):
            for n in range(lanes):
                u = self.front + (m + 0.5) * self.sub
                v = -self.half_width + (n + 0.5) * self.sub
                cells[m, n] = _index(x + u * cy - v * sy, y + u * sy + v * cy, self.sub, rows, cols)
        total = int(round(units * self.q * self.s * self.s))

        def prism(face: int) -> np.ndarray:
            return np.maximum(face - np.arange(depth, dtype=np.int64) * self.max_diff, 0)

        low, high = 0, total
        while low < high:  # the highest face whose prism holds at most ``total``
            mid = (low + high + 1) // 2
            if prism(mid).sum() * lanes <= total:
                low = mid
            else:
                high = mid - 1
        column = prism(low)
        share, rest = divmod(total - int(column.sum()) * lanes, lanes)
        column = np.repeat(column[:, None], lanes, axis=1)
        column[0] += share
        column[0, :rest] += 1
        if (cells[column > 0] < 0).any():
            raise SoilError(f"the pile ahead of a blade at ({x:.3f}, {y:.3f}) leaves the field")
        for m in range(depth):
            for n in range(lanes):
                if column[m, n]:
                    self.fine[cells[m, n, 0], cells[m, n, 1]] += column[m, n]
                    self.loose[cells[m, n, 0], cells[m, n, 1]] += column[m, n]

    def dig_in(self, x: float, y: float, yaw: float, metres: float) -> float:
        """Slipping wheels carry a layer as thick as their sinkage back, ``metres`` of it.

        The running gear's contact (two sides of ``contact_width``) shears the soil under
        it by the slipped distance: that much soil, at the wheels' sinkage, goes from under
        the rear half of the body to behind it, so a robot that spins in place digs itself
        in (its rear sinks, its nose rises, the grade grows). Soil moves in whole quanta per
        sub-cell: returns the part of ``metres`` not yet dug (the caller carries it on);
        all of it without terramechanics traction.
        """
        wheels = self.physics.wheels
        if wheels is None or metres <= 0.0:
            return max(metres, 0.0)
        band = int(round(self.site.cell / self.sub)) * int(round(2 * self.half_width / self.sub))
        per_metre = (
            (2 * self.params.contact_width * wheels.sinkage / (self.sub * self.sub * band))
            / self.site.unit
            * self.q
        )  # quanta per sub-cell per metre slipped
        take = int(metres * per_metre)
        if take <= 0:
            return metres
        dig_wheels(
            self.fine, self.loose, x, y, yaw, self.sub, self.site.cell, self.half_width, take
        )
        return metres - take / per_metre

    def pitch(self, x: float, y: float, yaw: float) -> float:
        """The body's nose-up pitch (rad): its front row's mean ground against its rear's."""
        cell = self.site.cell
        front, n_front = band_ground(self.fine, x, y, yaw, self.sub, 0.0, cell, self.half_width)
        rear, n_rear = band_ground(self.fine, x, y, yaw, self.sub, -cell, 0.0, self.half_width)
        if not n_front or not n_rear:
            return 0.0
        rise = (front / n_front - rear / n_rear) * self.site.unit / self.q
        return math.atan2(rise, cell)


# --- calibration ---------------------------------------------------------------------------


def level_pile_force(units: float, params: SoilParams, cell: float, unit: float, physics) -> float:
    """McKyes's force of a level blade on flat ground against ``units`` of soil.

    The soil is held against the blade as :meth:`Soil.heap` puts it. Deterministic.
    """
    probe = Soil(np.zeros((24, 24), dtype=np.int64), Site(24, 24, cell, unit), params, physics)
    x, y, yaw = 3 * cell, 6 * cell, 0.0
    probe.heap(x, y, yaw, units)
    return probe.resistance(x, y, yaw, probe.ground(x, y, yaw))


@lru_cache(maxsize=32)
def calibrate(
    params: SoilParams, cell: float, unit: float, capacities: tuple[int, int] = (12, 24)
) -> Physics:
    """The soil's physics with the motor forces set by the grid's push capacities.

    ``capacities``: the world profile's ``normal_load`` and ``throttle_load`` (12 and 24
    under ``v1``, 24 and 24 under ``paper``). Without throttle-up the motor stalls between
    a level push of ``capacities[0]`` units and one more on flat ground, with throttle-up
    likewise at ``capacities[1]``: each force is the mean of the two piles' resistances.
    The mass gives traction ``traction_margin`` times the larger force.
    """
    n_gamma, n_c, n_q, beta = n_factors(params)
    gamma = params.density * params.gravity
    cot = 1 / math.tan(math.radians(params.rake_angle)) + 1 / math.tan(beta)
    draft = Physics(
        gamma,
        params.cohesion,
        n_gamma,
        n_c,
        n_q,
        cot,
        math.tan(math.radians(params.friction_angle)),
        params.wheel_friction,
        params.gravity,
        (0.0, 0.0),
        0.0,
    )
    if params.calibration == "robot":
        return robot_physics(params, draft)
    forces = []
    for capacity in capacities:
        low = level_pile_force(capacity, params, cell, unit, draft)
        high = level_pile_force(capacity + 1, params, cell, unit, draft)
        if not high > low:
            raise SoilError(
                f"a level push of {capacity + 1} units meets no more resistance than one of "
                f"{capacity} ({high:.3g} N against {low:.3g} N): check pile_reach and "
                f"blade_height"
            )
        forces.append((low + high) / 2)
    mass = params.traction_margin * forces[1] / (params.wheel_friction * params.gravity)
    wheels = Terrain.of(params, mass) if params.traction == "terramechanics" else None
    return replace(draft, motor=(forces[0], forces[1]), mass=mass, wheels=wheels)


def robot_physics(params: SoilParams, draft: Physics) -> Physics:
    """The physics of ``calibration: robot``: the forces come from the robot.

    The full push is the drive's power over its pushing speed (``drive_power /
    push_speed``), or, with no power given, what the wheels' traction gives; without
    throttle-up the robot pushes ``normal_fraction`` of it. The blade takes at most
    ``blade_limit``; L1 reads ``load_full_scale`` (or the full push) as a full blade.
    """
    mass = params.robot_mass
    wheels = Terrain.of(params, mass) if params.traction == "terramechanics" else None
    traction = replace(draft, mass=mass, wheels=wheels).traction()
    if traction <= 0:
        raise SoilError(
            f"robot_mass = {mass}: the wheels' thrust does not overcome their rolling "
            f"resistance ({wheels.thrust(1.0):.3g} N against {wheels.rolling:.3g} N)"
        )
    full = params.drive_power / params.push_speed if params.drive_power > 0 else traction
    return replace(
        draft,
        motor=(params.normal_fraction * full, full),
        mass=mass,
        full_scale=params.load_full_scale or full,
        blade_limit=params.blade_limit,
        wheels=wheels,
    )


def stall_capacity(
    params: SoilParams, cell: float, unit: float, throttle: bool, most: float = 400.0
) -> float | None:
    """The level pile (units, to 0.01, on flat ground) at which a push stalls.

    The measured counterpart of the grid's push capacities (12 / 24 under ``v1``): the
    smallest pile whose McKyes force the robot cannot give (over ``blade_limit``, the
    motors or the wheels; with ``force_control`` the blade rises there instead of stalling,
    so it is the most a push carries). ``None`` when no pile up to ``most`` units (that
    fits the probe) stalls it.
    """
    physics = calibrate(params, cell, unit)

    def stalls(units: float) -> bool:
        force = level_pile_force(units, params, cell, unit, physics)
        return physics.speed_factor(force, force, throttle) == 0.0

    high = 0.25
    try:
        while not stalls(high):
            high *= 2
            if high > most:
                return None
    except SoilError:
        return None
    low = 0.0
    while high - low > 0.005:
        mid = (low + high) / 2
        if stalls(mid):
            high = mid
        else:
            low = mid
    return round(high, 2)
