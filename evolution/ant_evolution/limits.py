"""The evolution package's limits: command-line numbers and run configurations.

Every ``ant-eval`` / ``ant-evolve`` / ``ant-sweep`` / ``ant-experiment`` option and every
key of a run configuration is bounded here, and so are the products that size the big
arrays (scenarios x grid cells for the scenario set, scenarios x steps for the fitness
curves, population x scenarios for the fitness table), all checked before anything is
allocated. Each error names the option or key, the value and the limit;
``docs/reliability.md`` lists them.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable

from ant_controller.genome import DEFAULT_LATTICE
from ant_evolution.errors import ConfigError
from excavation_common.limits import MAX_DEPTH_UNITS, MAX_ROBOTS, MAX_TEXT_BYTES, int_in

MAX_CONFIG_BYTES = MAX_TEXT_BYTES
"""Largest run configuration file (1 MiB)."""
MAX_POPULATION = 10_000
MAX_GENERATIONS = 1_000_000
MAX_SCENARIOS = 100_000
MAX_STEPS = 100_000
MAX_WORKERS = 256
MAX_SEED = 2**63 - 1
"""Seeds are 0..2**63 - 1 (numpy's ``SeedSequence`` takes no negative entropy)."""
MAX_LIST = 64
"""Longest list option (``--robots-mix``, ``--depths``, ``ant-sweep --robots``)."""
MAX_NEURONS = (2 * DEFAULT_LATTICE.half_width + 1) ** 2 * DEFAULT_LATTICE.layers
"""Most neurons of an initial random tissue: one per site of the default lattice (867)."""
MAX_DOMAIN = 232
"""Highest ROS domain id (``--domain-base`` + workers must not pass it)."""
MAX_SCENARIO_CELLS = 1 << 28
"""Scenarios x grid cells (the scenario set's int32 heights: 1 GiB)."""
MAX_CURVE_POINTS = 1 << 27
"""Scenarios x (steps + 1) (``ant-eval``'s float64 fitness curves: 1 GiB)."""
MAX_FITNESS_ENTRIES = 1 << 27
"""Population x scenarios (a generation's fitness table)."""

INT_RANGES: dict[str, tuple[int, int]] = {
    "population": (2, MAX_POPULATION),
    "generations": (1, MAX_GENERATIONS),
    "scenarios": (1, MAX_SCENARIOS),
    "steps": (1, MAX_STEPS),
    "robots": (1, MAX_ROBOTS),
    "elitism": (0, MAX_POPULATION - 1),
    "seed": (0, MAX_SEED),
    "checkpoint_every": (1, MAX_GENERATIONS),
}
"""Range of each integer key of a run configuration (and of the option of the same name)."""
LIST_RANGES: dict[str, tuple[int, int]] = {
    "robots_mix": (1, MAX_ROBOTS),
    "robots_range": (1, MAX_ROBOTS),
    "depths": (1, MAX_DEPTH_UNITS),
    "neurons": (1, MAX_NEURONS),
}
"""Range of every element of each list key."""


def option(name: str) -> Callable[[str], int]:
    """The ``argparse`` type of the integer option for configuration key ``name``."""
    return int_in(*INT_RANGES[name])


def int_list(low: int, high: int) -> Callable[[str], tuple[int, ...]]:
    """An ``argparse`` type: a comma-separated list of at most ``MAX_LIST`` integers in range."""
    element = int_in(low, high)

    def parse(text: str) -> tuple[int, ...]:
        parts = [v for v in text.split(",") if v.strip()]
        if not parts:
            raise argparse.ArgumentTypeError("the list is empty")
        if len(parts) > MAX_LIST:
            raise argparse.ArgumentTypeError(
                f"{len(parts)} values, more than the limit of {MAX_LIST}"
            )
        return tuple(element(v.strip()) for v in parts)

    return parse


def check_config_value(path: str, key: str, value: object) -> None:
    """Refuse a configuration value outside its limit (the type is checked elsewhere).

    Raises:
        ConfigError: Naming ``path``, ``key``, the value and the limit.
    """
    if key in INT_RANGES and isinstance(value, int):
        low, high = INT_RANGES[key]
        if not low <= value <= high:
            raise ConfigError(path, key, value, f"must lie in {low}..{high} (the limit)")
    if key in LIST_RANGES and isinstance(value, list | tuple):
        low, high = LIST_RANGES[key]
        if len(value) > MAX_LIST:
            raise ConfigError(
                path, key, f"{len(value)} values", f"holds more than the limit of {MAX_LIST}"
            )
        for i, v in enumerate(value):
            if isinstance(v, int) and not low <= v <= high:
                raise ConfigError(path, f"{key}[{i}]", v, f"must lie in {low}..{high} (the limit)")


def check_workload(
    label: str, cells: int, scenarios: int, steps: int | None = None, population: int = 1
) -> None:
    """Refuse a run whose arrays would pass the product limits, before they are allocated.

    Args:
        label: Where the numbers came from (``<command line>`` or a config file).
        cells: Cells of the largest blueprint.
        scenarios: Scenarios evaluated together.
        steps: Timesteps whose fitness curve is kept (``ant-eval``), or None.
        population: Genomes per generation (``ant-evolve``).

    Raises:
        ConfigError: Naming the product, its value and the limit.
    """
    products = [("scenarios x grid cells", scenarios * cells, MAX_SCENARIO_CELLS)]
    if steps is not None:
        products.append(("scenarios x (steps + 1)", scenarios * (steps + 1), MAX_CURVE_POINTS))
    products.append(("population x scenarios", population * scenarios, MAX_FITNESS_ENTRIES))
    for name, value, limit in products:
        if value > limit:
            raise ConfigError(label, name, value, f"exceeds the limit of {limit}")
