"""The physical soil's presets as a table: every parameter, its value and its source.

``python -m excavation_sim.presets``: Markdown for docs/world-model.md ("Presets"): each
preset's parameters with their sources (``soil_presets.yaml``) and the measured push it
stalls at (:func:`excavation_sim.soil.stall_capacity`) beside the grid's capacities, on the
blueprint scale each preset is meant for, and one robot of each cutting flat ground.
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


VARIANTS = ("physical:dome,blade_limit=0",)
"""Readings beside the presets: the dome robot pushing with its wheels' force, no blade limit."""


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


def push_rows(metres: float = 2.0, speed: float = 0.15) -> list[str]:
    """One robot of each preset cuts flat ground with its blade set below (Markdown rows).

    Throttle up, ``speed`` m/s, no slip or noise, until it has covered ``metres`` or 4,000
    steps (200 s) have passed: how far it got, the steps its wheels could not give the push,
    and the soil it moved (the volume that ended anywhere higher than it started, kg).
    """
    import numpy as np

    from ant_controller.layout import BLADE_BELOW
    from blueprint_server.blueprint import default_blueprint
    from excavation_sim.dynamics import Dynamics, DynamicsParams
    from excavation_sim.world import COL, HEADING, ROW, World

    rows = [
        "| preset | covered, m | time, s | steps stalled | soil moved, kg |",
        "|---|---:|---:|---:|---:|",
    ]
    for spec in [*(f"physical:{name}" for name in PRESETS), *VARIANTS]:
        s = SCALES[spec.split(":")[1].split(",")[0]]
        bp = default_blueprint(1)
        world = World.scenario(bp.zones, bp.goal, 1, 0, 0)
        world.robots[0, [ROW, COL, HEADING]] = (6, 1, 1)  # facing east over open ground
        soil = SoilParams(soil=spec)
        dyn = Dynamics(
            world, DynamicsParams.exact(), s.cell, np.random.default_rng(0), soil, s.unit
        )
        dyn.set_blade(0, BLADE_BELOW)
        dyn.throttle[0] = True
        start, x0, steps = dyn.soil.fine.copy(), float(dyn.bodies[0, 0]), 0
        while dyn.bodies[0, 0] - x0 < metres and steps < 4000:
            dyn.command(0, speed, 0.0)
            dyn.step()
            steps += 1
        f = dyn.soil
        gained = float(np.clip(f.fine - start, 0, None).sum())
        kg = gained / f.q * s.unit * f.sub * f.sub * f.params.density
        rows.append(
            f"| `{spec}` | {dyn.bodies[0, 0] - x0:.2f} | {steps * dyn.params.dt:.0f} | "
            f"{dyn.counters.slips} | {kg:.1f} |"
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
    print("\n".join(push_rows()))
    print()
    print("\n".join(source_rows()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
