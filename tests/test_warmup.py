"""``python -m ant_evolution.warmup``: every kind compiles and runs; bad options are refused."""

import subprocess
import sys

import pytest

from ant_evolution import warmup


@pytest.mark.parametrize("kind", warmup.KINDS)
def test_every_kind_compiles_and_runs(kind):
    assert warmup.compile_kind(kind) >= 0.0


def test_main_reports_every_kind(capsys):
    assert warmup.main(["--workers", "1"]) == 0
    out = capsys.readouterr().out
    assert "kernels ready in" in out and all(f"{k} " in out for k in warmup.KINDS)


def test_zero_workers_is_refused():
    proc = subprocess.run(
        [sys.executable, "-m", "ant_evolution.warmup", "--workers", "0"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2 and "--workers: must be at least 1, got 0" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_scenario_arrays_have_one_type_however_the_set_arrived():
    """A set made here and one unpickled (as a pool worker gets it) give the kernel the same
    argument types, so the kernel the warm-up compiled is the one every worker loads."""
    import pickle

    import numba

    from ant_evolution.evaluate import ScenarioSet
    from blueprint_server.blueprint import default_blueprint

    batch = ScenarioSet.create(default_blueprint(1), 2, 2, 10, 0)
    here, there = batch.arrays(), pickle.loads(pickle.dumps(batch)).arrays()
    assert numba.typeof(here) == numba.typeof(there)
    assert all(not a.flags.writeable for a in here)
    assert batch.heights.flags.writeable  # the set's own arrays are left as they were


def test_the_cache_key_covers_every_file_with_kernels(monkeypatch):
    """The cache folder's hash covers every source file that uses numba in the three kernel
    packages (the episode kernel inlines code from ant_evolution/baselines/network.py), and
    changes when one of them is left out."""
    import importlib.util
    from pathlib import Path

    import ant_controller

    covered: set[Path] = set()
    for name, patterns in ant_controller.KERNEL_SOURCES.items():
        root = Path(importlib.util.find_spec(name).submodule_search_locations[0])
        covered |= {p.resolve() for pattern in patterns for p in root.glob(pattern)}
        for path in root.rglob("*.py"):
            if "numba" in path.read_text(encoding="utf-8"):
                assert path.resolve() in covered, f"{path} uses numba but is not hashed"
    full = ant_controller.source_hash()
    monkeypatch.setitem(ant_controller.KERNEL_SOURCES, "ant_evolution", ("*.py",))
    assert ant_controller.source_hash() != full
