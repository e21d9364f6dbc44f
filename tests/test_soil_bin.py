"""The physical soil's blade force against published measurements (a soil bin).

excavation_sim/blade_forces.yaml holds the measured points with their source and the
tolerance fixed before any comparison (25 %); excavation_sim.soil_bin drives a blade
through a level bed of the measured sand with the model's own kernels.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from excavation_sim.soil import Site, Soil, calibrate
from excavation_sim.soil_bin import (
    BED,
    UNIT,
    BladeForceDataError,
    bin_params,
    error,
    load,
    readings,
    table_rows,
)


def test_the_data_hold_every_point_with_its_source_and_the_tolerance():
    tolerance, sets = load()
    assert tolerance == 0.25
    (obermayr,) = sets
    assert "10.1016/j.jterra.2011.08.003" in obermayr.source
    assert "digitised" in obermayr.read
    assert len(obermayr.points) == 8
    assert {p.width for p in obermayr.points} == {0.2, 0.3}
    assert obermayr.soil["density"] == 1440.0 and obermayr.rake_angle == 90.0


def test_a_malformed_data_file_names_the_field():
    with pytest.raises(BladeForceDataError, match="format"):
        load("format: other\n")
    bad = (
        "format: ant-blade-forces/1\ntolerance: 0.25\nsets:\n- name: x\n  source: s\n"
        "  read: r\n  soil: {}\n  blade: {rake_angle: 90}\n  averaged_over: [0.5, 1.5]\n"
        "  points: [[0.2, -0.1, 280]]\n"
    )
    with pytest.raises(BladeForceDataError, match="points"):
        load(bad)


def test_the_bin_reads_mckyes_for_a_cut_and_more_with_the_heap():
    """The bin is a real experiment: deeper cuts and wider blades take more force, the
    equation's cut-only value grows with the square of the depth, the heap only adds."""
    _, [(_, found)] = readings()
    by = {(r.point.width, r.point.depth): r for r in found}
    for width in (0.2, 0.3):
        for kind in ("cut_only", "physical"):
            forces = [getattr(by[(width, d)], kind) for d in (0.10, 0.15, 0.20, 0.25)]
            assert forces == sorted(forces), (width, kind, forces)
    for r in found:
        assert r.physical > r.cut_only > 0
    assert by[(0.3, 0.2)].physical > by[(0.2, 0.2)].physical


def test_the_bin_bed_is_firm_and_its_heap_loose():
    """What the blade cuts becomes loose; the bed ahead stays firm; soil is conserved."""
    _, [data] = load()
    point = data.points[1]
    params = bin_params(data)
    cell = point.width / 2
    site = Site(12, 40, cell, UNIT)
    soil = Soil(
        np.full((12, 40), int(BED / UNIT), dtype=np.int64),
        site,
        params,
        calibrate(params, cell, UNIT),
    )
    total = soil.volume()
    edge = int(round((BED - point.depth) / UNIT * soil.q))
    x, y = 2 * cell, 6 * cell
    bodies, on = np.zeros((1, 3)), np.array([True])
    for _ in range(40):
        x += soil.sub / 2
        soil.cut(x, y, 0.0, edge)
        bodies[0] = (x, y, 0.0)
        soil.settle(bodies, on, on)
    assert soil.volume() == total
    assert (soil.loose >= 0).all() and (soil.loose <= soil.fine).all()
    load_ = soil.load(x, y, 0.0, edge)
    assert math.isclose(load_.depth, point.depth, rel_tol=0.02)
    assert load_.over > 0  # the heap lies on the failure wedge
    ahead = (np.arange(40 * soil.s) + 0.5) * soil.sub > x + soil.front + 2.0
    assert soil.loose[:, ahead].sum() == 0


def test_the_docs_table_is_what_the_bin_prints():
    text = (Path(__file__).parent.parent / "docs" / "world-model.md").read_text()
    start = text.index("<!-- soil-bin -->\n") + len("<!-- soil-bin -->\n")
    end = text.index("<!-- /soil-bin -->")
    assert text[start:end].strip() == "\n".join(table_rows()), (
        "rerun python -m excavation_sim.soil_bin"
    )


def test_the_physical_soil_is_within_the_tolerance_of_every_measurement():
    tolerance, results = readings()
    outside = [
        f"{r.point}: {r.physical:.0f} N ({100 * error(r.physical, r.point.force):+.0f} %)"
        for _, found in results
        for r in found
        if abs(error(r.physical, r.point.force)) > tolerance
    ]
    assert not outside, "outside the tolerance: " + "; ".join(outside)
