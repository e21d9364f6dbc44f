"""The experiments of the paper's section 5 by command name (``ant-experiment NAME``).

Every experiment has its module (``training``, ``compare``, ``coarse_coding``, ``scaleup``,
``antagonism``, ``long_run`` for ``depth`` and ``area``, ``evolve_robots``, ``behaviours``),
each with a pure ``compute`` step that returns the rows of its CSV and a ``run`` step that
takes a :class:`~.core.Context`, trains or loads what it needs, computes and writes into
``OUT/<name>/`` through the shared writers (:mod:`.figures` for the PNGs, :mod:`.sections`
for ``section.md``). ``docs/experiments.md`` describes each one against the paper.
"""

from __future__ import annotations

from collections.abc import Callable

from ant_evolution.experiments import (
    antagonism,
    coarse_coding,
    compare,
    evolve_robots,
    long_run,
    scaleup,
    training,
)
from ant_evolution.experiments.core import Context

EXPERIMENTS: dict[str, Callable[[Context], None]] = {
    "training": training.run,
    "compare": compare.run,
    "coarse-coding": coarse_coding.run,
    "scaleup": scaleup.run,
    "antagonism": antagonism.run,
    "depth": long_run.depth,
    "area": long_run.area,
    "evolve-robots": evolve_robots.run,
}
"""Every experiment but ``behaviours``, which needs the Table 3 detectors (:func:`experiments`)."""


def experiments() -> dict[str, Callable[[Context], None]]:
    """Every experiment that can run here: ``behaviours`` where its detectors are installed."""
    out = dict(EXPERIMENTS)
    try:
        from ant_evolution.experiments import behaviours
    except ImportError:  # the Table 3 detectors are not installed
        return out
    out["behaviours"] = behaviours.run
    return out
