"""``field-metrics``: the paper's field-trial table from a before and an after height map.

Usage::

    field-metrics before.npy after.npy --blueprint default:1 [--png diff.png] [--json]

Maps are ``.npy`` (float, metres, ``[rows, cols]``, row 0 = southern edge, NaN = not
measured; what the mapper node writes with ``save_dir``) or ``.csv`` (same, comma
separated, the southern row first). The blueprint (``default``, ``default:D``,
``landing-pad`` or a file) gives zones, goal depths and the soil unit; the tolerance is a
quarter of a soil unit unless ``--tolerance`` (metres) says otherwise. ``--png`` draws the
difference (after - before) as a heat map with the dig and dump zones outlined. A bad file
ends with exit code 2 and a message naming the file, the field and the value.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from excavation_common.limits import MAX_GRID_CELLS, MAX_GRID_SIDE
from terrain_mapper.errors import MapperError
from terrain_mapper.metrics import DIG, DUMP, FieldMetrics, difference, field_metrics


def load_map(path: str, shape: tuple[int, int] | None = None) -> np.ndarray:
    """A height map from ``.npy`` or ``.csv``.

    Raises:
        MapperError: Missing or unreadable file, wrong dtype, dimension or shape.
    """
    p = Path(path)
    if not p.is_file():
        raise MapperError(path, "file", None, "does not exist")
    _check_map_size(path, p)
    try:
        if p.suffix == ".npy":
            grid = np.load(p, allow_pickle=False)
        elif p.suffix == ".csv":
            grid = np.loadtxt(p, delimiter=",", ndmin=2)
        else:
            raise MapperError(path, "suffix", p.suffix, "expected .npy or .csv")
    except (ValueError, OSError) as exc:
        raise MapperError(path, "content", None, f"cannot be read: {exc}") from None
    if grid.ndim != 2 or grid.dtype.kind not in "fiu":
        raise MapperError(path, "array", f"{grid.dtype} {grid.shape}", "expected a 2-D number grid")
    if shape is not None and grid.shape != tuple(shape):
        raise MapperError(path, "shape", grid.shape, f"the blueprint is {shape[0]} x {shape[1]}")
    return grid.astype(np.float64)


MAX_MAP_BYTES = 64 << 20
"""Largest height-map file (64 MiB: a 1024 x 1024 float64 map is 8 MiB, as CSV about 20)."""


def _check_map_size(label: str, p: Path) -> None:
    """Refuse a too large map file before anything is read into memory.

    The file must hold at most ``MAX_MAP_BYTES``; an ``.npy`` header must describe a 2-D
    grid within the worksite limits (``MAX_GRID_SIDE``, ``MAX_GRID_CELLS``).
    """
    size = p.stat().st_size
    if size > MAX_MAP_BYTES:
        raise MapperError(
            label, "file", f"{size} bytes", f"is larger than the limit of {MAX_MAP_BYTES} bytes"
        )
    if p.suffix != ".npy":
        return
    try:
        with p.open("rb") as f:
            fmt = np.lib.format
            version = fmt.read_magic(f)
            read = fmt.read_array_header_1_0 if version == (1, 0) else fmt.read_array_header_2_0
            shape, _, _ = read(f)
    except (ValueError, OSError, SyntaxError) as exc:
        raise MapperError(label, "header", None, f"is not a .npy header: {exc}") from None
    if len(shape) != 2 or shape[0] * shape[1] > MAX_GRID_CELLS or max(shape) > MAX_GRID_SIDE:
        raise MapperError(
            label,
            "shape",
            list(shape),
            f"expected a 2-D grid of at most {MAX_GRID_SIDE} a side and {MAX_GRID_CELLS} cells",
        )


def draw_difference(
    before: np.ndarray,
    after: np.ndarray,
    zones: np.ndarray,
    metrics: FieldMetrics,
    path: str,
    height_unit: float = 1.0,
) -> None:
    """Heat map of ``after - before`` in soil units (north up), dig and dump zones outlined.

    The colour range is symmetric and covers 95% of the changes (at least one unit), so a
    few tall mounds do not wash out the pit; larger values take the end colours.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    diff = difference(before, after) / height_unit
    rows, cols = diff.shape
    finite = np.abs(diff[np.isfinite(diff)])
    span = max(float(np.percentile(finite, 95)) if finite.size else 1.0, 1.0)
    fig, ax = plt.subplots(figsize=(6, 5.2), dpi=100)
    im = ax.imshow(
        diff, origin="lower", cmap="RdBu", vmin=-span, vmax=span, extent=(0, cols, 0, rows)
    )
    for code, colour, style in ((DUMP, "green", "solid"), (DIG, "black", "dashed")):
        ax.contour(
            (zones == code).astype(float),
            levels=[0.5],
            colors=colour,
            linewidths=2,
            linestyles=style,
            extent=(0, cols, 0, rows),
            origin="lower",
        )
    label = "after - before (soil units): red dug, blue raised"
    fig.colorbar(im, ax=ax, extend="both", label=label)
    ax.set_xlabel("column (east)")
    ax.set_ylabel("row (north)")
    ax.set_title(
        f"towards goal {metrics.towards_goal:.0%}, above {metrics.above_goal:.0%}, "
        f"below {metrics.below_goal:.0%}, indeterminate {metrics.indeterminate:.0%}\n"
        f"deposited soil in dump zones {metrics.dump_share:.0%} "
        "(dashed: dig area; green: dump zones)",
        fontsize=9,
    )
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def format_table(m: FieldMetrics) -> str:
    """The metrics as the paper's field-trial table (plain text)."""
    lines = [
        "area   system response",
        f"{m.towards_goal:6.1%} correctly excavated towards goal depth",
        f"{m.above_goal:6.1%} above goal depth",
        f"{m.below_goal:6.1%} below goal depth",
        f"{m.indeterminate:6.1%} indeterminate",
        f"deposited soil in dump zones: {m.dump_share:.1%} "
        f"(removed {m.removed:.3f}, deposited {m.deposited:.3f}, map unit x cells)",
    ]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``field-metrics``."""
    parser = argparse.ArgumentParser(prog="field-metrics", description=__doc__.split("\n\n")[0])
    parser.add_argument("before", help="height map before the run (.npy or .csv, metres)")
    parser.add_argument("after", help="height map after the run (.npy or .csv, metres)")
    parser.add_argument("--blueprint", default="default", help="blueprint spec or file")
    parser.add_argument("--tolerance", type=float, default=None, help="metres (unit / 4)")
    parser.add_argument("--png", help="draw the difference heat map here")
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")
    args = parser.parse_args(argv)
    from blueprint_server.blueprint import resolve_blueprint
    from excavation_common.errors import FieldError

    try:
        bp = resolve_blueprint(args.blueprint)
        before = load_map(args.before, bp.shape)
        after = load_map(args.after, bp.shape)
    except FieldError as exc:
        print(f"field-metrics: error: {exc}", file=sys.stderr)
        return 2
    tolerance = bp.height_unit / 4 if args.tolerance is None else args.tolerance
    if not tolerance >= 0:
        print(f"field-metrics: error: --tolerance = {tolerance}: must be >= 0", file=sys.stderr)
        return 2
    m = field_metrics(before, after, bp.zones, bp.goal * bp.height_unit, tolerance)
    if args.json:
        print(json.dumps(m.as_dict()))
    else:
        print(format_table(m))
    if args.png:
        draw_difference(before, after, bp.zones, m, args.png, bp.height_unit)
        if not args.json:
            print(f"difference heat map: {args.png}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
