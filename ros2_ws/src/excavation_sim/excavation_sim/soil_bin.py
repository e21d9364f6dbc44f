"""A soil bin: the physical soil's blade force against published measurements.

``python -m excavation_sim.soil_bin`` prints, for every measured point of
``blade_forces.yaml`` (a flat blade cutting a level bed of dry sand at a fixed depth, the
horizontal force averaged over a stretch of travel), two readings of this project's model
beside the measurement:

* **the physical soil** as ``dynamics`` runs it: the blade's edge held at the cutting
  depth in a level bed of the measured sand, moved forward half a sub-cell at a time; each
  step cuts (:meth:`Soil.cut`), relaxes the field to the angle of repose
  (:meth:`Soil.settle`) and reads the force (:meth:`Soil.resistance`): McKyes's equation
  with the firm bed cut as its depth and the loose soil heaped on the failure wedge as its
  surcharge, plus the drag of any loose soil beyond the wedge;
* **McKyes, cut only**: the earth-moving equation with the cutting depth as its depth and
  no surcharge (the two-dimensional textbook value, McKyes 1985, chapter 4), for scale:
  what the heap in front of the blade adds.

The test (tests/test_soil_bin.py) holds the tolerance the data file fixes (25 %). The
bin's scale follows the model's geometry: the blade spans two cells (cell = width / 2),
soil units of 1 cm, a bed 0.40 m deep; the sand's density, friction, cohesion and the
blade's friction are the measured ones; its repose is taken at its friction angle and the
blade is tall enough that nothing spills over it (the report gives neither).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from importlib import resources

import numpy as np
import yaml

from excavation_common.params import validate
from excavation_sim.soil import Site, Soil, SoilParams, calibrate, mckyes_force

UNIT = 0.01
"""Soil unit of the bin, m."""
BED = 0.40
"""Depth of the level bed, m."""
BLADE_HEIGHT = 0.6
"""Blade height, m: no heap reaches over it."""


class BladeForceDataError(ValueError):
    """The data file is malformed (names the field)."""


@dataclass(frozen=True)
class Point:
    """One measured condition: blade width and cutting depth (m), horizontal force (N)."""

    width: float
    depth: float
    force: float


@dataclass(frozen=True)
class DataSet:
    """One published series: its soil, blade, travel window, points and source."""

    name: str
    source: str
    read: str
    caveats: str
    soil: dict
    rake_angle: float
    averaged_over: tuple[float, float]
    points: tuple[Point, ...]


def load(text: str | None = None) -> tuple[float, list[DataSet]]:
    """The tolerance and the data sets of ``blade_forces.yaml`` (or of ``text``).

    Raises:
        BladeForceDataError: Naming the field that is missing or malformed.
    """
    if text is None:
        text = resources.files("excavation_sim").joinpath("blade_forces.yaml").read_text()
    doc = yaml.safe_load(text)
    where = "blade_forces.yaml"
    if not isinstance(doc, dict) or doc.get("format") != "ant-blade-forces/1":
        raise BladeForceDataError(f"{where}: format must be ant-blade-forces/1")
    try:
        tolerance = float(doc["tolerance"])
        sets = []
        for i, s in enumerate(doc["sets"]):
            points = tuple(Point(*map(float, p)) for p in s["points"])
            if not points or any(p.width <= 0 or p.depth <= 0 or p.force <= 0 for p in points):
                raise BladeForceDataError(f"{where}: sets[{i}].points: positive triples")
            window = tuple(float(v) for v in s["averaged_over"])
            sets.append(
                DataSet(
                    str(s["name"]),
                    " ".join(str(s["source"]).split()),
                    " ".join(str(s["read"]).split()),
                    " ".join(str(s.get("caveats", "")).split()),
                    dict(s["soil"]),
                    float(s["blade"]["rake_angle"]),
                    (window[0], window[1]),
                    points,
                )
            )
    except (KeyError, TypeError, ValueError) as exc:
        if isinstance(exc, BladeForceDataError):
            raise
        raise BladeForceDataError(f"{where}: {exc!r}") from None
    return tolerance, sets


def bin_params(data: DataSet) -> SoilParams:
    """The physical soil's parameters for the measured sand and blade (module docstring)."""
    soil = data.soil
    return validate(
        SoilParams,
        {
            "soil": "physical",
            "density": soil["density"],
            "friction_angle": soil["friction_angle"],
            "cohesion": soil["cohesion"],
            "blade_friction_angle": math.degrees(math.atan(soil["blade_friction"])),
            "rake_angle": data.rake_angle,
            "repose_angle": soil["friction_angle"],
            "blade_height": BLADE_HEIGHT,
        },
        node="soil_bin",
    )


@dataclass(frozen=True)
class Reading:
    """The model's horizontal force (N) for one point, two ways (module docstring)."""

    point: Point
    physical: float
    cut_only: float


def soil_bin(data: DataSet, point: Point) -> Reading:
    """Drive a blade through a level bed at ``point``'s depth; the forces over the window."""
    params = bin_params(data)
    cell = point.width / 2  # the model's blade spans two cells (Soil.half_width = cell)
    start, end = data.averaged_over
    rows, cols = 12, int(math.ceil((end + 1.0) / cell)) + 4
    site = Site(rows, cols, cell, UNIT)
    bed = int(round(BED / UNIT))
    physics = calibrate(params, cell, UNIT)
    soil = Soil(np.full((rows, cols), bed, dtype=np.int64), site, params, physics)
    edge = int(round((BED - point.depth) / UNIT * soil.q))
    y, x = rows * cell / 2, 2 * cell
    blade0 = x + soil.front
    bodies, active, down = np.zeros((1, 3)), np.array([True]), np.array([True])
    physical = []
    while x + soil.front - blade0 < end:
        x += soil.sub / 2
        soil.cut(x, y, 0.0, edge)
        bodies[0] = (x, y, 0.0)
        soil.settle(bodies, active, down)
        if x + soil.front - blade0 >= start:
            physical.append(soil.resistance(x, y, 0.0, edge))
    cut_only = mckyes_force(point.depth, 0.0, point.width, 1.0, physics)
    return Reading(point, float(np.mean(physical)), cut_only)


def readings() -> tuple[float, list[tuple[DataSet, list[Reading]]]]:
    """Every data set's points read three ways, with the tolerance."""
    tolerance, sets = load()
    return tolerance, [(s, [soil_bin(s, p) for p in s.points]) for s in sets]


def error(model: float, measured: float) -> float:
    """Relative error of ``model`` against ``measured``."""
    return (model - measured) / measured


def table_rows() -> list[str]:
    """Markdown rows: each point, the measurement and the two readings with their errors."""
    tolerance, results = readings()
    rows = [
        "| blade width, m | cutting depth, m | measured, N | physical soil, N "
        "| McKyes, cut only, N |",
        "|---:|---:|---:|---:|---:|",
    ]

    def cell(value: float, measured: float) -> str:
        e = error(value, measured)
        mark = "" if abs(e) <= tolerance else " ✗"
        return f"{value:.0f} ({100 * e:+.0f} %){mark}"

    for _, found in results:
        for r in found:
            p = r.point
            rows.append(
                f"| {p.width:.2f} | {p.depth:.2f} | {p.force:.0f} | {cell(r.physical, p.force)} "
                f"| {cell(r.cut_only, p.force)} |"
            )
    return rows


def main() -> None:
    """Print the validation table (docs/world-model.md)."""
    print("\n".join(table_rows()))


if __name__ == "__main__":
    main()
