"""The soak's machinery (``ant-soak``, ``make soak``): memory sampling, growth bounds, and a
short soak through the nodes with full perception that misses no tick."""

from __future__ import annotations

import json
import os

import pytest
from excavation_field.soak import main, memory_growth, rss_mb, violations


def samples(per_tick: float, ticks: int = 1000, every: int = 50) -> list[dict]:
    """Synthetic samples: one steady process and one growing ``per_tick`` MB a tick."""
    return [
        {"tick": t, "rss": {"steady": 100.0 + (t % 100) * 0.01, "leaky": 80.0 + per_tick * t}}
        for t in range(0, ticks + 1, every)
    ]


def test_rss_of_this_process_and_of_a_gone_one():
    """Touching 200 MB raises this process's reading by about that much; a gone pid reads
    None."""
    import numpy as np

    before = rss_mb(os.getpid())
    block = np.ones(200 * 2**20, dtype=np.uint8)  # written, so resident
    after = rss_mb(os.getpid())
    assert 190.0 < after - before < 260.0
    del block
    assert rss_mb(2**22 + 12345) is None


def test_growth_is_measured_after_the_warmup():
    growth = {g.name: g for g in memory_growth(samples(0.01), warmup=100)}
    assert growth["leaky"].start_mb == pytest.approx(81.0)
    assert growth["leaky"].growth_mb == pytest.approx(9.0)
    assert growth["leaky"].slope_mb_per_1000 == pytest.approx(10.0)
    assert abs(growth["steady"].slope_mb_per_1000) < 0.5
    lines = violations(list(growth.values()), max_growth=5.0, max_slope=1.0)
    assert len(lines) == 2 and all(line.startswith("leaky") for line in lines)
    assert violations(list(growth.values()), max_growth=50.0, max_slope=20.0) == []
    with pytest.raises(ValueError, match="samples after the warm-up"):
        memory_growth(samples(0.0), warmup=5000)


def test_bad_arguments_are_one_line(capsys):
    assert main(["--steps", "3"]) == 2
    assert "--steps = 3: must be at least 10" in capsys.readouterr().err


@pytest.mark.system
@pytest.mark.serial  # promises no missed tick on an unloaded machine (run alone)
def test_short_soak_through_the_nodes(tmp_path, capsys, domain):
    """2 robots, 40 ticks, full perception, every node a process: sampled, nothing missed."""
    out = tmp_path / "soak.json"
    code = main(
        [
            "--hand-coded",
            "--robots",
            "2",
            "--steps",
            "40",
            "--interval",
            "0.5",
            "--warmup",
            "5",
            "--max-growth",
            "200",
            "--max-slope",
            "10000",
            "--domain",
            str(domain),
            "--json",
            str(out),
            "--plot",
            str(tmp_path / "soak.png"),
        ]
    )
    assert code == 0, capsys.readouterr().err
    summary = json.loads(out.read_text())
    assert summary["missed"] == {"0": 0, "1": 0}
    names = {g["name"] for g in summary["growth"]}
    assert {"sim", "server", "sensors", "localizer", "mapper", "controller_0"} <= names
    assert {"blade_driver_0", "blade_driver_1", "controller_1"} <= names
    assert all(g["start_mb"] > 10 for g in summary["growth"])  # real processes
    assert len(summary["samples"]) >= 3
    assert (tmp_path / "soak.png").stat().st_size > 1000
