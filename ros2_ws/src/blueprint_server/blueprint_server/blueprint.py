"""Excavation blueprints: which cells to dig and how deep, where to dump (paper, section 4).

A :class:`Blueprint` is a grid of zones (0 don't care, 1 dig, 2 dump) with a goal height
for every dig cell (negative soil units: ``-d`` means ``d`` units below ground), plus the
cell size and the height of one soil unit in metres. Row 0 is the southern edge of the
worksite (``map`` y grows with the row), column 0 the western edge.

Sources:

* generators: :func:`default_blueprint` (the paper's 8 x 8 pit in a 16 x 16 site),
  :func:`pit_blueprint` (any rectangular pit with a dump band), :func:`landing_pad`
  (the paper's 9 x 10.5 x 2.0 m pad with a 5.0 x 3.5 x 1.0 m ramp at any cell size);
* YAML files (``format: ant-blueprint/1``) in a parametric form (grid, pit, dump band)
  or a per-cell form (rows of characters, northern row first, as drawn on a map);
* images plus a scale (metres per pixel), see :func:`from_image`.

Every loader raises :class:`BlueprintError` naming the file, the field and the value, and
checks the limits of :mod:`blueprint_server.limits` (grid cells, depths, file size, image
pixels) before it allocates a grid or decodes an image. This module imports no ``rclpy``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from blueprint_server.errors import BlueprintError
from blueprint_server.limits import (
    CELL_SIZE_RANGE,
    HEIGHT_UNIT_RANGE,
    MAX_BLUEPRINT_BYTES,
    MAX_DEPTH_UNITS,
    check_depth,
    check_grid,
)
from excavation_common.constants import ZONE_DIG as DIG  # noqa: F401 (zone codes)
from excavation_common.constants import ZONE_DONT_CARE as DONT_CARE  # noqa: F401
from excavation_common.constants import ZONE_DUMP as DUMP  # noqa: F401
from excavation_common.loaders import check_image, load_yaml

FORMAT = "ant-blueprint/1"


DEFAULT_CELL_SIZE = 0.25
"""Metres per cell when a file does not say (the dome robots are about 0.5 m long)."""
DEFAULT_HEIGHT_UNIT = 0.05
"""Metres per soil unit when a file does not say."""

# Per-cell form characters.
CHAR_DONT_CARE = "."
CHAR_DUMP = "D"


@dataclass(frozen=True)
class Blueprint:
    """Zones and goal heights of a worksite.

    Attributes:
        zones: ``uint8 [rows, cols]``, 0 don't care, 1 dig, 2 dump.
        goal: ``int32 [rows, cols]`` goal height in soil units on dig cells, 0 elsewhere.
        cell_size: Edge of a grid cell in metres.
        height_unit: Height of one soil unit in metres.
        name: Where the blueprint came from (file name or generator call).
    """

    zones: np.ndarray
    goal: np.ndarray
    cell_size: float = DEFAULT_CELL_SIZE
    height_unit: float = DEFAULT_HEIGHT_UNIT
    name: str = field(default="blueprint", compare=False)

    def __post_init__(self) -> None:
        zones = np.ascontiguousarray(self.zones, dtype=np.uint8)
        goal = np.ascontiguousarray(self.goal, dtype=np.int32)
        if zones.ndim != 2 or zones.shape != goal.shape:
            raise BlueprintError(
                self.name, "zones", zones.shape, f"must be 2-D and match goal {goal.shape}"
            )
        if np.any(zones > DUMP):
            raise BlueprintError(self.name, "zones", int(zones.max()), "zone codes are 0, 1, 2")
        goal = np.where(zones == DIG, goal, 0).astype(np.int32)
        zones.setflags(write=False)
        goal.setflags(write=False)
        object.__setattr__(self, "zones", zones)
        object.__setattr__(self, "goal", goal)

    @property
    def shape(self) -> tuple[int, int]:
        """Grid ``(rows, cols)``."""
        return self.zones.shape

    @property
    def dig_cells(self) -> int:
        """Number of cells to excavate."""
        return int(np.count_nonzero(self.zones == DIG))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Blueprint):
            return NotImplemented
        return (
            np.array_equal(self.zones, other.zones)
            and np.array_equal(self.goal, other.goal)
            and self.cell_size == other.cell_size
            and self.height_unit == other.height_unit
        )

    __hash__ = None  # type: ignore[assignment]

    def to_rows(self) -> list[str]:
        """Per-cell form: one string per row, northern row first.

        Raises:
            BlueprintError: When a goal is deeper than 9 units (one character per cell).
        """
        deepest = int(-self.goal.min()) if self.goal.size else 0
        if deepest > 9:
            raise BlueprintError(
                self.name,
                "goal",
                -deepest,
                "the per-cell form holds depths 1-9 only; "
                "use a coarser height_unit or the parametric form",
            )
        out = []
        for r in range(self.shape[0] - 1, -1, -1):
            chars = []
            for c in range(self.shape[1]):
                z = self.zones[r, c]
                if z == DIG:
                    chars.append(str(-int(self.goal[r, c])))
                else:
                    chars.append(CHAR_DUMP if z == DUMP else CHAR_DONT_CARE)
            out.append("".join(chars))
        return out

    def to_yaml(self) -> str:
        """The per-cell YAML form, loadable by :func:`load_blueprint`."""
        return yaml.safe_dump(
            {
                "format": FORMAT,
                "cell_size": self.cell_size,
                "height_unit": self.height_unit,
                "rows": self.to_rows(),
            },
            sort_keys=False,
        )


# --- generators -----------------------------------------------------------------------------


def pit_blueprint(
    grid: tuple[int, int] = (16, 16),
    pit_size: tuple[int, int] = (8, 8),
    depth: int = 1,
    dump_band: int = 2,
    origin: tuple[int, int] | None = None,
    cell_size: float = DEFAULT_CELL_SIZE,
    height_unit: float = DEFAULT_HEIGHT_UNIT,
    name: str | None = None,
) -> Blueprint:
    """A rectangular pit of ``depth`` units with a dump band around it.

    Args:
        grid: ``(rows, cols)`` of the worksite.
        pit_size: ``(rows, cols)`` of the pit.
        depth: Goal depth below ground, soil units (>= 1).
        dump_band: Width in cells of the dump ring around the pit (clipped at the edges).
        origin: South-west cell ``(row, col)`` of the pit; centred when omitted.
        cell_size: Metres per cell.
        height_unit: Metres per soil unit.
        name: Label; a description of the call by default.

    Raises:
        BlueprintError: When the pit does not fit or a size is not positive.
    """
    label = name or f"pit {pit_size[0]}x{pit_size[1]} depth {depth} in {grid[0]}x{grid[1]}"
    rows, cols = (int(v) for v in grid)
    pr, pc = (int(v) for v in pit_size)
    for fname, value in (("grid", grid), ("pit.size", pit_size)):
        if min(value) < 1:
            raise BlueprintError(label, fname, list(value), "sizes must be positive")
        check_grid(label, fname, int(value[0]), int(value[1]))
    check_depth(label, "pit.depth", int(depth))
    if not 0 <= dump_band <= max(rows, cols):
        raise BlueprintError(
            label,
            "dump_band",
            dump_band,
            f"must be 0 or more, at most {max(rows, cols)} (the grid's side)",
        )
    if origin is None:
        origin = ((rows - pr) // 2, (cols - pc) // 2)
    r0, c0 = (int(v) for v in origin)
    if r0 < 0 or c0 < 0 or r0 + pr > rows or c0 + pc > cols:
        raise BlueprintError(
            label,
            "pit.origin",
            [r0, c0],
            f"a {pr} x {pc} pit there leaves the {rows} x {cols} grid",
        )
    zones = np.zeros((rows, cols), dtype=np.uint8)
    b = dump_band
    zones[max(0, r0 - b) : r0 + pr + b, max(0, c0 - b) : c0 + pc + b] = DUMP
    zones[r0 : r0 + pr, c0 : c0 + pc] = DIG
    goal = np.where(zones == DIG, -depth, 0)
    return Blueprint(zones, goal, cell_size, height_unit, name=label)


def default_blueprint(depth: int = 1, fitted: bool = False) -> Blueprint:
    """The paper's training site: an 8 x 8 pit of ``depth`` units with a dump band of 2.

    Args:
        depth: Goal depth, soil units.
        fitted: The grid is the pit plus its dump band (12 x 12, the paper profile's
            ``site = "fitted"``); False: the pit centred in 16 x 16.
    """
    if fitted:
        return pit_blueprint((12, 12), (8, 8), depth, 2, name=f"default 12x12 (depth {depth})")
    return pit_blueprint((16, 16), (8, 8), depth, 2, name=f"default (depth {depth})")


def landing_pad(
    cell_size: float = 0.5,
    height_unit: float = 0.25,
    dump_band_m: float = 1.0,
    margin_m: float = 1.0,
) -> Blueprint:
    """The paper's landing pad: a 9 x 10.5 m pit 2.0 m deep with a 5.0 x 3.5 m ramp 1.0 m deep.

    The pad's 10.5 m side runs east-west; the ramp (5.0 m along the pad's edge, 3.5 m
    long) leaves the pad's southern edge in its middle. A dump band of ``dump_band_m``
    surrounds both, and ``margin_m`` of don't-care ground surrounds the band. Lengths are
    rounded to whole cells and depths to whole soil units.

    Raises:
        BlueprintError: When a size is not positive or rounds to zero cells.
    """
    label = f"landing pad (cell {cell_size} m, unit {height_unit} m)"
    for fname, value, (lo, hi) in (
        ("cell_size", cell_size, CELL_SIZE_RANGE),
        ("height_unit", height_unit, HEIGHT_UNIT_RANGE),
    ):
        if not (isinstance(value, int | float) and math.isfinite(value) and lo <= value <= hi):
            raise BlueprintError(label, fname, value, f"must lie in {lo}..{hi} metres")
    for fname, value in (("dump_band_m", dump_band_m), ("margin_m", margin_m)):
        if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0):
            raise BlueprintError(label, fname, value, "must be 0 or more metres")

    def cells(m: float, fname: str) -> int:
        n = int(round(m / cell_size))
        if n < 1:
            raise BlueprintError(label, fname, m, f"rounds to 0 cells at {cell_size} m per cell")
        return n

    pad_r, pad_c = cells(9.0, "pad.length"), cells(10.5, "pad.width")
    ramp_len, ramp_w = cells(3.5, "ramp.length"), cells(5.0, "ramp.width")
    band = int(round(dump_band_m / cell_size))
    margin = int(round(margin_m / cell_size))
    pad_depth = max(1, int(round(2.0 / height_unit)))
    ramp_depth = max(1, int(round(1.0 / height_unit)))
    check_depth(label, "pad.depth", pad_depth)
    rows = margin + band + ramp_len + pad_r + band + margin
    cols = margin + band + pad_c + band + margin
    check_grid(label, "grid", rows, cols)
    zones = np.zeros((rows, cols), dtype=np.uint8)
    goal = np.zeros((rows, cols), dtype=np.int32)
    pad_r0 = margin + band + ramp_len
    pad_c0 = margin + band
    ramp_c0 = pad_c0 + (pad_c - ramp_w) // 2
    ramp_r0 = margin + band
    zones[pad_r0 - band : pad_r0 + pad_r + band, pad_c0 - band : pad_c0 + pad_c + band] = DUMP
    zones[ramp_r0 - band : pad_r0, ramp_c0 - band : ramp_c0 + ramp_w + band] = DUMP
    zones[pad_r0 : pad_r0 + pad_r, pad_c0 : pad_c0 + pad_c] = DIG
    goal[pad_r0 : pad_r0 + pad_r, pad_c0 : pad_c0 + pad_c] = -pad_depth
    zones[ramp_r0:pad_r0, ramp_c0 : ramp_c0 + ramp_w] = DIG
    goal[ramp_r0:pad_r0, ramp_c0 : ramp_c0 + ramp_w] = -ramp_depth
    return Blueprint(zones, goal, cell_size, height_unit, name=label)


# --- files ----------------------------------------------------------------------------------

_PARAMETRIC_KEYS = {"format", "cell_size", "height_unit", "grid", "pit", "dump_band"}
_PER_CELL_KEYS = {"format", "cell_size", "height_unit", "rows"}
_IMAGE_KEYS = {"format", "cell_size", "height_unit", "image", "scale", "max_depth"}
_PIT_KEYS = {"size", "depth", "origin"}


def _positive_number(
    path: str, data: dict, key: str, default: float, limits: tuple[float, float] | None = None
) -> float:
    value = data.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int | float) or not _finite(value):
        raise BlueprintError(path, key, value, "must be a finite number")
    if value <= 0:
        raise BlueprintError(path, key, value, "must be positive")
    if limits is not None and not limits[0] <= value <= limits[1]:
        raise BlueprintError(path, key, value, f"must lie in {limits[0]}..{limits[1]} (the limit)")
    return float(value)


def _finite(value: int | float) -> bool:
    try:
        return math.isfinite(value)
    except OverflowError:  # an integer too large for a float
        return False


def _int_pair(path: str, key: str, value: object) -> tuple[int, int]:
    if (
        not isinstance(value, list | tuple)
        or len(value) != 2
        or not all(isinstance(v, int) and not isinstance(v, bool) for v in value)
    ):
        raise BlueprintError(path, key, value, "must be a list of two integers [rows, cols]")
    return int(value[0]), int(value[1])


def _check_keys(path: str, where: str, data: dict, allowed: set[str]) -> None:
    unknown = sorted(set(data) - allowed)
    if unknown:
        raise BlueprintError(
            path,
            f"{where}{unknown[0]}",
            data[unknown[0]],
            f"unknown key (allowed: {sorted(allowed)})",
        )


def blueprint_from_dict(data: object, path: str = "<memory>") -> Blueprint:
    """Build a blueprint from a parsed ``ant-blueprint/1`` mapping.

    Raises:
        BlueprintError: Naming ``path``, the field and the value at fault.
    """
    if not isinstance(data, dict):
        raise BlueprintError(path, "<root>", type(data).__name__, "must be a mapping")
    if data.get("format") != FORMAT:
        raise BlueprintError(path, "format", data.get("format"), f"must be '{FORMAT}'")
    cell_size = _positive_number(path, data, "cell_size", DEFAULT_CELL_SIZE, CELL_SIZE_RANGE)
    height_unit = _positive_number(
        path, data, "height_unit", DEFAULT_HEIGHT_UNIT, HEIGHT_UNIT_RANGE
    )
    forms = [k for k in ("rows", "pit", "image") if k in data]
    if len(forms) != 1:
        raise BlueprintError(
            path, "rows|pit|image", forms, "give exactly one of 'rows', 'pit' or 'image'"
        )
    if forms[0] == "rows":
        _check_keys(path, "", data, _PER_CELL_KEYS)
        return _from_rows(path, data["rows"], cell_size, height_unit)
    if forms[0] == "image":
        _check_keys(path, "", data, _IMAGE_KEYS)
        image = data["image"]
        if not isinstance(image, str):
            raise BlueprintError(path, "image", image, "must be a file name")
        image_path = (Path(path).parent / image) if path != "<memory>" else Path(image)
        if "scale" not in data:
            raise BlueprintError(path, "scale", None, "is required with 'image' (metres per pixel)")
        scale = _positive_number(path, data, "scale", 1.0)
        max_depth = _positive_number(path, data, "max_depth", 3 * height_unit)
        try:
            return from_image(image_path, scale, cell_size, height_unit, max_depth)
        except BlueprintError as exc:  # name the blueprint file, and the image in the reason
            raise BlueprintError(
                path, exc.field, exc.value, f"{exc.reason} [{image_path}]"
            ) from None
    _check_keys(path, "", data, _PARAMETRIC_KEYS)
    grid = _int_pair(path, "grid", data.get("grid", [16, 16]))
    pit = data["pit"]
    if not isinstance(pit, dict):
        raise BlueprintError(path, "pit", pit, "must be a mapping with size, depth, origin")
    _check_keys(path, "pit.", pit, _PIT_KEYS)
    size = _int_pair(path, "pit.size", pit.get("size", [8, 8]))
    depth = pit.get("depth", 1)
    if not isinstance(depth, int) or isinstance(depth, bool):
        raise BlueprintError(path, "pit.depth", depth, "must be an integer number of soil units")
    origin = _int_pair(path, "pit.origin", pit["origin"]) if "origin" in pit else None
    band = data.get("dump_band", 2)
    if not isinstance(band, int) or isinstance(band, bool):
        raise BlueprintError(path, "dump_band", band, "must be an integer number of cells")
    try:
        return pit_blueprint(grid, size, depth, band, origin, cell_size, height_unit, name=path)
    except BlueprintError as exc:
        raise BlueprintError(path, exc.field, exc.value, exc.reason) from None


def _from_rows(path: str, rows: object, cell_size: float, height_unit: float) -> Blueprint:
    if not isinstance(rows, list) or not rows or not all(isinstance(r, str) for r in rows):
        raise BlueprintError(path, "rows", rows, "must be a non-empty list of strings")
    width = len(rows[0])
    n = len(rows)
    check_grid(path, "rows", n, width)
    zones = np.zeros((n, width), dtype=np.uint8)
    goal = np.zeros((n, width), dtype=np.int32)
    for i, line in enumerate(rows):
        if len(line) != width:
            raise BlueprintError(
                path, f"rows[{i}]", line, f"has {len(line)} cells, row 0 has {width}"
            )
        r = n - 1 - i  # first line is the northern edge
        for c, ch in enumerate(line):
            if ch == CHAR_DONT_CARE:
                continue
            if ch == CHAR_DUMP:
                zones[r, c] = DUMP
            elif ch in "123456789":
                zones[r, c] = DIG
                goal[r, c] = -int(ch)
            else:
                raise BlueprintError(
                    path, f"rows[{i}][{c}]", ch, "use '.' don't care, 'D' dump, '1'-'9' dig depth"
                )
    return Blueprint(zones, goal, cell_size, height_unit, name=path)


def from_image(
    path: str | Path,
    scale: float,
    cell_size: float = DEFAULT_CELL_SIZE,
    height_unit: float = DEFAULT_HEIGHT_UNIT,
    max_depth: float | None = None,
) -> Blueprint:
    """A blueprint from a picture of the site, top of the image = north.

    Colours: white (all channels >= 250) is don't care; green (G at least 64 above both
    R and B) is dump; any other pixel is dig, its depth ``(255 - gray) / 255 * max_depth``
    metres (black = ``max_depth``), rounded to soil units (at least 1). Each cell takes the
    most common class of the pixels it covers and the mean depth of its dig pixels.

    Args:
        path: PNG (or any format OpenCV reads).
        scale: Metres per pixel.
        cell_size: Metres per cell.
        height_unit: Metres per soil unit.
        max_depth: Depth in metres of a black pixel (default three soil units).

    Raises:
        BlueprintError: Unreadable image, bad scale, or an image smaller than one cell.
    """
    import cv2

    label = str(path)
    if max_depth is None:
        max_depth = 3 * height_unit
    if not (math.isfinite(scale) and scale > 0):
        raise BlueprintError(label, "scale", scale, "must be a positive number of metres per pixel")
    if not (math.isfinite(max_depth) and 0 < max_depth / height_unit <= MAX_DEPTH_UNITS):
        raise BlueprintError(
            label,
            "max_depth",
            max_depth,
            f"must be positive and at most {MAX_DEPTH_UNITS} soil units "
            f"({MAX_DEPTH_UNITS * height_unit:g} m, the limit)",
        )
    try:
        w, h = check_image(label, BlueprintError)  # header only: pixels within the limits
    except BlueprintError as exc:
        raise BlueprintError(label, "image", exc.value, exc.reason) from None
    px_per_cell = cell_size / scale
    rows, cols = int(h / px_per_cell), int(w / px_per_cell)
    if rows < 1 or cols < 1:
        raise BlueprintError(
            label, "scale", scale, f"a {w} x {h} image is smaller than one {cell_size} m cell"
        )
    check_grid(label, "scale", rows, cols)
    image = cv2.imread(label, cv2.IMREAD_COLOR)
    if image is None or image.shape[:2] != (h, w):
        raise BlueprintError(label, "image", label, "cannot be read as an image")
    b, g, r = (image[..., i].astype(np.int32) for i in range(3))
    white = (b >= 250) & (g >= 250) & (r >= 250)
    green = (g - r >= 64) & (g - b >= 64)
    dig = ~white & ~green
    gray = (b + g + r) / 3.0
    depth_m = (255.0 - gray) / 255.0 * max_depth
    zones = np.zeros((rows, cols), dtype=np.uint8)
    goal = np.zeros((rows, cols), dtype=np.int32)
    for i in range(rows):
        y0, y1 = int(round(i * px_per_cell)), int(round((i + 1) * px_per_cell))
        r_cell = rows - 1 - i
        for c in range(cols):
            x0, x1 = int(round(c * px_per_cell)), int(round((c + 1) * px_per_cell))
            counts = (
                white[y0:y1, x0:x1].sum(),
                dig[y0:y1, x0:x1].sum(),
                green[y0:y1, x0:x1].sum(),
            )
            zone = int(np.argmax(counts))
            zones[r_cell, c] = zone
            if zone == DIG:
                d = depth_m[y0:y1, x0:x1][dig[y0:y1, x0:x1]].mean()
                goal[r_cell, c] = -max(1, int(round(d / height_unit)))
    return Blueprint(zones, goal, cell_size, height_unit, name=label)


def load_blueprint(path: str | Path) -> Blueprint:
    """Load a blueprint from YAML (``ant-blueprint/1``) or from an image file.

    To load an image, write a small YAML with ``image:`` (path relative to the YAML) and
    ``scale:`` (metres per pixel), or call :func:`from_image`.

    Raises:
        BlueprintError: Naming the file, field and value at fault.
    """
    label = str(Path(path))
    data = load_yaml(label, BlueprintError, max_bytes=MAX_BLUEPRINT_BYTES)
    return blueprint_from_dict(data, label)


def resolve_blueprint(spec: str | None, depth: int = 1, fitted: bool = False) -> Blueprint:
    """The one blueprint resolver of the suite (command lines, node parameters, configs).

    Args:
        spec: ``None`` or ``"default"`` (the default pit at ``depth``), ``"default:D"``
            (goal depth ``D``), ``"fitted"`` / ``"fitted:D"`` (the same pit on the grid of
            the pit plus its dump band, the paper profile's site), ``"landing-pad"``, or
            the path of a blueprint file.
        depth: Goal depth of a plain ``"default"`` or ``"fitted"``.
        fitted: The default pit on a grid of the pit plus its dump band (see
            :func:`default_blueprint`); files and the landing pad keep their own grid.

    Raises:
        BlueprintError: A bad depth, or a file that is missing or malformed.
    """
    if spec is None or spec in ("default", "fitted"):
        return default_blueprint(depth, fitted or spec == "fitted")
    if spec == "landing-pad":
        return landing_pad()
    if spec.startswith(("default:", "fitted:")):
        text = spec.partition(":")[2]
        if not text.isdigit() or int(text) < 1:
            raise BlueprintError(spec, "depth", text, "must be a positive integer")
        if len(text) > 6 or int(text) > MAX_DEPTH_UNITS:
            raise BlueprintError(
                spec, "depth", text, f"must lie in 1..{MAX_DEPTH_UNITS} soil units (the limit)"
            )
        return default_blueprint(int(text), fitted or spec.startswith("fitted:"))
    return load_blueprint(spec)
