"""``blueprint_info``: validate a blueprint and print (or draw) it.

Usage: ``ros2 run blueprint_server blueprint_info site.yaml [--png out.png]``; the
argument may also be ``default``, ``default:D`` (goal depth D) or ``landing-pad``.
Exit code 2 with a message naming the file, field and value when it is malformed.
"""

from __future__ import annotations

import argparse
import sys

from blueprint_server.blueprint import (
    DIG,
    DUMP,
    Blueprint,
    resolve_blueprint,
)
from blueprint_server.errors import BlueprintError


def save_png(blueprint: Blueprint, path: str) -> None:
    """Draw zones and goal depths (north up) to a PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    shown = np.where(blueprint.zones == DIG, blueprint.goal, np.nan).astype(float)
    fig, ax = plt.subplots(figsize=(5, 5), dpi=100)
    rows, cols = blueprint.shape
    ax.imshow(
        blueprint.zones == DUMP,
        origin="lower",
        cmap="Greens",
        alpha=0.4,
        extent=(0, cols, 0, rows),
    )
    im = ax.imshow(shown, origin="lower", cmap="Blues_r", extent=(0, cols, 0, rows))
    fig.colorbar(im, ax=ax, label="goal height (soil units)")
    ax.set_title(f"{blueprint.name}\n{cols} x {rows} cells of {blueprint.cell_size} m", fontsize=9)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    """Entry point."""
    parser = argparse.ArgumentParser(prog="blueprint_info", description=__doc__.split("\n\n")[0])
    parser.add_argument("blueprint", help="YAML file, 'default', 'default:D' or 'landing-pad'")
    parser.add_argument("--png", help="also draw it to this PNG file")
    parser.add_argument("--rows", action="store_true", help="print the per-cell YAML form")
    args = parser.parse_args(argv)
    try:
        bp = resolve_blueprint(args.blueprint)
    except BlueprintError as exc:
        print(f"blueprint_info: error: {exc}", file=sys.stderr)
        return 2
    rows, cols = bp.shape
    print(f"{bp.name}: {rows} rows x {cols} cols, cell {bp.cell_size} m, unit {bp.height_unit} m")
    print(
        f"dig cells {bp.dig_cells}, dump cells {int((bp.zones == DUMP).sum())}, "
        f"goal depths {sorted({-int(g) for g in bp.goal[bp.zones == DIG]})}"
    )
    if args.rows:
        print(bp.to_yaml(), end="")
    if args.png:
        save_png(bp, args.png)
        print(f"wrote {args.png}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
