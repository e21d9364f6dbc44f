"""The limits every package shares: file sizes, nesting, image pixels, the worksite's extent.

Each limit is checked before anything is allocated from the value it bounds, and an error
that a limit raises names the file, the field, the value and the limit (see
``docs/reliability.md``, "Limits", which lists these and every package's own limits).

World limits and the kernels' integer type: soil heights, goal heights and their sums are
``int32`` in the world model and the batched kernels. A goal of ``-d`` units on every cell
of the largest grid moves ``MAX_GRID_CELLS * MAX_DEPTH_UNITS`` units of soil in all; twice
that (a difference of two such sums) stays below ``2**31 - 1``, so no sum the kernels take
over a grid can overflow. ``tests/test_broken_inputs.py`` checks the inequality.

Command-line helpers: :func:`int_in` is an ``argparse`` type that refuses a number outside
its range with a message naming the limit.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable

# --- files ----------------------------------------------------------------------------------

MAX_TEXT_BYTES = 1 << 20
"""Largest YAML or JSON file a loader reads unless its package sets its own (1 MiB)."""
MAX_NESTING = 32
"""Deepest nesting of mappings and lists in a YAML or JSON file."""
MAX_IMAGE_BYTES = 64 << 20
"""Largest image file read (64 MiB)."""
MAX_IMAGE_SIDE = 16384
"""Widest or tallest image in pixels, read from its header before decoding."""
MAX_IMAGE_PIXELS = 4096 * 4096
"""Most pixels in an image (16.8 Mpx: 50 MB decoded as BGR), read from its header."""

# --- the worksite ---------------------------------------------------------------------------

MAX_GRID_SIDE = 4096
"""Most rows or columns of a worksite grid."""
MAX_GRID_CELLS = 1 << 20
"""Most cells of a worksite grid (1,048,576; e.g. 1024 x 1024)."""
MAX_DEPTH_UNITS = 500
"""Deepest goal below ground (and highest mound) of one cell, soil units."""
MAX_ROBOTS = 64
"""Largest team (64 robots of 2 x 2 cells fill a 16 x 16 site)."""

INT32_MAX = 2**31 - 1
"""The kernels' soil type is ``int32``."""


def int_in(low: int, high: int) -> Callable[[str], int]:
    """An ``argparse`` type: an integer in ``low..high``, else a message naming the range.

    Args:
        low: Smallest accepted value.
        high: Largest accepted value (the limit).

    Returns:
        A function from the option's text to the integer.
    """

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f"{value} is outside {low}..{high} (the limit)")
        return value

    parse.__name__ = f"integer {low}..{high}"
    return parse


def float_in(low: float, high: float) -> Callable[[str], float]:
    """An ``argparse`` type: a finite number in ``low..high``, else a message naming the range."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
        if not low <= value <= high:  # NaN fails this too
            raise argparse.ArgumentTypeError(f"{value} is outside {low}..{high} (the limit)")
        return value

    parse.__name__ = f"number {low}..{high}"
    return parse
