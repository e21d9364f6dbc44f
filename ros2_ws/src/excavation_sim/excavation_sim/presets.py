"""The physical soil's presets as a table: every parameter, its value and its source.

``python -m excavation_sim.presets``: Markdown for docs/world-model.md ("Presets"): each
preset's parameters with their sources (``soil_presets.yaml``) and the measured push it
stalls at (:func:`excavation_sim.soil.stall_capacity`) beside the grid's capacities, on the
blueprint scale each preset is meant for.
"""

from __future__ import annotations

from dataclasses import dataclass

from excavation_sim.soil import PRESETS, SoilParams, calibrate, stall_capacity


@dataclass(frozen=True)
class Scale:
    """The blueprint scale a preset runs on: cell size and soil unit, m."""

    cell: float
    unit: float
    what: str


SCALES = {
    "grid": Scale(0.25, 0.05, "the default blueprint: 0.25 m cells, 0.05 m units"),
    "dome": Scale(0.25, 0.05, "the default blueprint: 0.25 m cells, 0.05 m units"),
    "lunar": Scale(0.25, 0.25, "the quarter-scale landing pad: 0.25 m cells, 0.25 m units"),
}


def capacity_rows() -> list[str]:
    """One Markdown row per preset: forces, mass, and the measured stall capacities."""
    rows = [
        "| preset | scale | push without / with throttle-up, N | mass, kg | L1 full at, N "
        "| stalls at (units of a level pile), without / with throttle-up | the grid's (v1) |",
        "|---|---|---|---|---|---|---|",
    ]
    for name in PRESETS:
        p = SoilParams(soil=f"physical:{name}").resolved()
        s = SCALES[name]
        physics = calibrate(p, s.cell, s.unit)
        caps = [stall_capacity(p, s.cell, s.unit, t) for t in (False, True)]
        kg = [None if c is None else c * s.cell * s.cell * s.unit * p.density for c in caps]
        stall = " / ".join(
            "none" if c is None else f"{c:.2f} ({m:.1f} kg)" for c, m in zip(caps, kg, strict=True)
        )
        limit = f"; blade {physics.blade_limit:g} N" if physics.blade_limit else ""
        rows.append(
            f"| `physical:{name}` | {s.what} | {physics.motor[0]:.1f} / {physics.motor[1]:.1f}"
            f"{limit} | {physics.mass:.1f} | {physics.load_scale():.1f} | {stall} | 12 / 24 |"
        )
    return rows


def source_rows() -> list[str]:
    """Every preset parameter with its value and source (Markdown rows)."""
    rows = ["| preset | parameter | value | source |", "|---|---|---|---|"]
    for name, preset in PRESETS.items():
        for key, value in preset.values.items():
            rows.append(f"| {name} | `{key}` | {value} | {preset.sources[key]} |")
    return rows


def main() -> int:
    """Print both tables."""
    print("\n".join(capacity_rows()))
    print()
    print("\n".join(source_rows()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
