"""The blueprint server's limits: what a blueprint file, image or generator call may ask for.

Checked before any grid is allocated; each error names the file, the field, the value and
the limit. The worksite limits themselves (grid side and cells, depth in soil units) are
the suite's, from :mod:`excavation_common.limits`; ``docs/reliability.md`` lists them all.
"""

from __future__ import annotations

from blueprint_server.errors import BlueprintError
from excavation_common.limits import (
    MAX_DEPTH_UNITS,
    MAX_GRID_CELLS,
    MAX_GRID_SIDE,
    MAX_IMAGE_PIXELS,
    MAX_IMAGE_SIDE,
    MAX_NESTING,
)

__all__ = [
    "CELL_SIZE_RANGE",
    "HEIGHT_UNIT_RANGE",
    "MAX_BLUEPRINT_BYTES",
    "MAX_DEPTH_UNITS",
    "MAX_GRID_CELLS",
    "MAX_GRID_SIDE",
    "MAX_IMAGE_PIXELS",
    "MAX_IMAGE_SIDE",
    "MAX_NESTING",
    "check_depth",
    "check_grid",
]

MAX_BLUEPRINT_BYTES = 2 << 20
"""Largest blueprint YAML (2 MiB: the per-cell form of the largest grid fits)."""
CELL_SIZE_RANGE = (0.001, 100.0)
"""Accepted ``cell_size``, metres (1 mm to 100 m)."""
HEIGHT_UNIT_RANGE = (0.0001, 10.0)
"""Accepted ``height_unit``, metres per soil unit (0.1 mm to 10 m)."""


def check_grid(label: str, field: str, rows: int, cols: int) -> None:
    """Refuse a grid of more than ``MAX_GRID_SIDE`` a side or ``MAX_GRID_CELLS`` cells.

    Raises:
        BlueprintError: Naming ``label``, ``field``, the size and the limit.
    """
    if max(rows, cols) > MAX_GRID_SIDE:
        raise BlueprintError(
            label, field, [rows, cols], f"exceeds the limit of {MAX_GRID_SIDE} cells a side"
        )
    if rows * cols > MAX_GRID_CELLS:
        raise BlueprintError(
            label,
            field,
            [rows, cols],
            f"has {rows * cols} cells, more than the limit of {MAX_GRID_CELLS}",
        )


def check_depth(label: str, field: str, depth: int) -> None:
    """Refuse a goal depth outside ``1..MAX_DEPTH_UNITS`` soil units.

    Raises:
        BlueprintError: Naming ``label``, ``field``, the depth and the limit.
    """
    if not 1 <= depth <= MAX_DEPTH_UNITS:
        raise BlueprintError(
            label,
            field,
            depth,
            f"must lie in 1..{MAX_DEPTH_UNITS} soil units (the limit; heights are int32)",
        )
