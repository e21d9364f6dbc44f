"""Field metrics between a "before" and an "after" height map (paper, section 6.2).

The dome trials were scored by comparing overhead laser scans taken before and after a run:
which share of the dig area was excavated towards the goal depth, which share is still
above it, which share the scans cannot tell, and how much of the displaced soil ended up in
the dump zones. :func:`field_metrics` computes those figures from two height maps (any
unit, NaN = not measured) and the blueprint's zones and goal. Pure numpy, no ``rclpy``, so
bag reports and tests can call it directly.

Rules for a dig cell (``tolerance`` in the maps' unit, default a quarter of a soil unit):

* **indeterminate**: unknown (NaN) in either map;
* **towards goal**: within ``tolerance`` of the goal after the run, or strictly closer to
  the goal than before by more than ``tolerance``, without passing below it by more than
  ``tolerance``;
* **below goal**: dug deeper than the goal by more than ``tolerance`` (over-excavated);
* **above goal**: every other known dig cell (not dug, or soil dumped on it).

Displaced soil: ``removed`` is the sum of height losses and ``deposited`` the sum of
height gains larger than ``tolerance`` over cells known in both maps; the dump share is the
part of ``deposited`` that lies in dump zones.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from excavation_common.constants import ZONE_DIG as DIG  # noqa: F401 (zone codes)
from excavation_common.constants import ZONE_DONT_CARE as DONT_CARE  # noqa: F401
from excavation_common.constants import ZONE_DUMP as DUMP  # noqa: F401


@dataclass(frozen=True)
class FieldMetrics:
    """Shares of the dig area and of the deposited soil (fractions in 0..1).

    Attributes:
        towards_goal: Share of dig cells excavated towards (or to) the goal depth.
        above_goal: Share of dig cells still above the goal depth (or raised).
        below_goal: Share of dig cells dug deeper than the goal.
        indeterminate: Share of dig cells unknown in either map.
        dump_share: Share of deposited soil that lies in dump zones (NaN if none deposited).
        removed: Soil removed (sum of height losses, map unit x cells).
        deposited: Soil deposited (sum of height gains, map unit x cells).
        dig_cells: Number of dig cells.
    """

    towards_goal: float
    above_goal: float
    below_goal: float
    indeterminate: float
    dump_share: float
    removed: float
    deposited: float
    dig_cells: int

    def as_dict(self) -> dict:
        """Plain dict (JSON-ready)."""
        return asdict(self)


def check_maps(before: np.ndarray, after: np.ndarray, zones: np.ndarray, goal: np.ndarray) -> None:
    """Raise ``ValueError`` unless the four grids are 2-D and of one shape."""
    shapes = {np.shape(a) for a in (before, after, zones, goal)}
    if len(shapes) != 1 or len(next(iter(shapes))) != 2:
        raise ValueError(
            f"before, after, zones and goal must be 2-D grids of one shape, got "
            f"{[np.shape(a) for a in (before, after, zones, goal)]}"
        )


def field_metrics(
    before: np.ndarray,
    after: np.ndarray,
    zones: np.ndarray,
    goal: np.ndarray,
    tolerance: float = 0.25,
) -> FieldMetrics:
    """Field metrics of a run from its before and after height maps.

    Args:
        before: Heights before the run, ``[rows, cols]``, NaN = not measured.
        after: Heights after the run, same shape and unit.
        zones: Blueprint zones (0 don't care, 1 dig, 2 dump).
        goal: Goal heights of the dig cells, same unit as the maps.
        tolerance: Height differences up to this are measurement noise.

    Returns:
        The shares and volumes, see :class:`FieldMetrics`.

    Raises:
        ValueError: Grids of different shapes or a negative tolerance.
    """
    check_maps(before, after, zones, goal)
    if not tolerance >= 0:
        raise ValueError(f"tolerance = {tolerance!r}: must be >= 0")
    before = np.asarray(before, dtype=np.float64)
    after = np.asarray(after, dtype=np.float64)
    goal = np.asarray(goal, dtype=np.float64)
    dig = np.asarray(zones) == DIG
    known = np.isfinite(before) & np.isfinite(after)
    n_dig = int(dig.sum())

    with np.errstate(invalid="ignore"):
        gap_before = np.abs(before - goal)
        gap_after = np.abs(after - goal)
        at_goal = gap_after <= tolerance
        below = after < goal - tolerance
        closer = (gap_after < gap_before - tolerance) & ~below
        towards = dig & known & (at_goal | closer)
        below_goal = dig & known & below & ~towards
        above = dig & known & ~towards & ~below_goal
        change = np.where(known, after - before, 0.0)
    gains = np.where(change > tolerance, change, 0.0)
    losses = np.where(change < -tolerance, -change, 0.0)
    deposited = float(gains.sum())
    in_dump = float(gains[np.asarray(zones) == DUMP].sum())

    def share(mask: np.ndarray) -> float:
        return float(mask.sum()) / n_dig if n_dig else float("nan")

    return FieldMetrics(
        towards_goal=share(towards),
        above_goal=share(above),
        below_goal=share(below_goal),
        indeterminate=share(dig & ~known),
        dump_share=in_dump / deposited if deposited > 0 else float("nan"),
        removed=float(losses.sum()),
        deposited=deposited,
        dig_cells=n_dig,
    )


def difference(before: np.ndarray, after: np.ndarray) -> np.ndarray:
    """``after - before`` per cell (NaN where either is unknown)."""
    return np.asarray(after, dtype=np.float64) - np.asarray(before, dtype=np.float64)
