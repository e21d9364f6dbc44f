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
