"""Tests for blueprint_server.blueprint, its errors and the blueprint_info CLI."""

from __future__ import annotations

import math
import re
from pathlib import Path

import cv2
import numpy as np
import pytest

from blueprint_server import blueprint_info
from blueprint_server.blueprint import (
    DIG,
    DONT_CARE,
    DUMP,
    FORMAT,
    Blueprint,
    blueprint_from_dict,
    default_blueprint,
    from_image,
    landing_pad,
    load_blueprint,
    pit_blueprint,
    resolve_blueprint,
)
from blueprint_server.errors import BlueprintError

# --- helpers --------------------------------------------------------------------------------


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def dilate(mask: np.ndarray, band: int) -> np.ndarray:
    """Square (Chebyshev) dilation of a boolean mask by ``band`` cells, clipped at the edges."""
    rows, cols = mask.shape
    out = np.zeros_like(mask, dtype=bool)
    for r, c in zip(*np.nonzero(mask), strict=True):
        out[max(0, r - band) : r + band + 1, max(0, c - band) : c + band + 1] = True
    assert out.shape == (rows, cols)
    return out


def bounding_box(mask: np.ndarray) -> tuple[int, int, int, int]:
    """``(row_min, row_max, col_min, col_max)`` of the true cells, inclusive."""
    rs, cs = np.nonzero(mask)
    return int(rs.min()), int(rs.max()), int(cs.min()), int(cs.max())


def assert_error_names_file(exc: BlueprintError, path: Path) -> None:
    assert exc.path == str(path)
    assert str(path) in str(exc)


# --- 1. default blueprint -------------------------------------------------------------------


@pytest.mark.parametrize("depth", [1, 2, 3])
def test_default_blueprint_layout(depth: int) -> None:
    bp = default_blueprint(depth)
    assert bp.shape == (16, 16)
    assert bp.zones.dtype == np.uint8
    assert bp.goal.dtype == np.int32
    assert bp.cell_size == 0.25
    assert bp.height_unit == 0.05

    expected_dig = np.zeros((16, 16), dtype=bool)
    expected_dig[4:12, 4:12] = True
    assert np.array_equal(bp.zones == DIG, expected_dig)
    assert bp.dig_cells == 64

    assert np.all(bp.goal[4:12, 4:12] == -depth)
    assert np.all(bp.goal[~expected_dig] == 0)
    assert sorted(np.unique(bp.goal).tolist()) == [-depth, 0]

    expected_dump = np.zeros((16, 16), dtype=bool)
    expected_dump[2:14, 2:14] = True
    expected_dump &= ~expected_dig
    assert np.array_equal(bp.zones == DUMP, expected_dump)
    assert int(np.count_nonzero(bp.zones == DUMP)) == 12 * 12 - 64 == 80

    assert int(np.count_nonzero(bp.zones == DONT_CARE)) == 256 - 144
    assert np.all(bp.zones[:2, :] == DONT_CARE)
    assert np.all(bp.zones[14:, :] == DONT_CARE)
    assert np.all(bp.zones[:, :2] == DONT_CARE)
    assert np.all(bp.zones[:, 14:] == DONT_CARE)


def test_blueprint_arrays_are_read_only() -> None:
    bp = default_blueprint(1)
    with pytest.raises(ValueError):
        bp.zones[0, 0] = DIG
    with pytest.raises(ValueError):
        bp.goal[5, 5] = -7


def test_blueprint_zeroes_goal_outside_dig_cells() -> None:
    zones = np.array([[DIG, DUMP], [DONT_CARE, DIG]])
    goal = np.array([[-2, -5], [-6, -1]])
    bp = Blueprint(zones, goal)
    assert bp.goal.tolist() == [[-2, 0], [0, -1]]
    assert bp.dig_cells == 2


def test_blueprint_rejects_bad_arrays() -> None:
    with pytest.raises(BlueprintError) as info:
        Blueprint(np.zeros((2, 3)), np.zeros((3, 2)))
    assert info.value.field == "zones"
    with pytest.raises(BlueprintError) as info:
        Blueprint(np.full((2, 2), 3), np.zeros((2, 2)))
    assert info.value.field == "zones"
    assert info.value.value == 3


def test_blueprint_equality_ignores_name_only() -> None:
    a = pit_blueprint(name="a")
    b = pit_blueprint(name="b")
    assert a == b
    assert a != pit_blueprint(depth=2)
    assert a != pit_blueprint(cell_size=0.5)
    assert a != pit_blueprint(height_unit=0.1)
    assert a != pit_blueprint(dump_band=1)
    assert (a == "not a blueprint") is False


# --- 2. pit_blueprint -----------------------------------------------------------------------


def test_pit_blueprint_explicit_origin_and_rectangular_grid() -> None:
    bp = pit_blueprint(grid=(10, 20), pit_size=(3, 5), depth=4, dump_band=1, origin=(2, 12))
    assert bp.shape == (10, 20)
    assert bounding_box(bp.zones == DIG) == (2, 4, 12, 16)
    assert bp.dig_cells == 15
    assert np.all(bp.goal[2:5, 12:17] == -4)
    assert int(np.count_nonzero(bp.goal)) == 15
    assert bounding_box(bp.zones == DUMP) == (1, 5, 11, 17)
    assert int(np.count_nonzero(bp.zones == DUMP)) == 5 * 7 - 15
    assert "3x5" in bp.name and "depth 4" in bp.name


def test_pit_blueprint_centres_odd_remainders_towards_south_west() -> None:
    bp = pit_blueprint(grid=(7, 9), pit_size=(2, 4), dump_band=0)
    # (7 - 2) // 2 = 2, (9 - 4) // 2 = 2
    assert bounding_box(bp.zones == DIG) == (2, 3, 2, 5)
    assert int(np.count_nonzero(bp.zones == DUMP)) == 0


def test_pit_blueprint_dump_band_is_clipped_at_the_edges() -> None:
    bp = pit_blueprint(grid=(6, 6), pit_size=(2, 2), depth=1, dump_band=2, origin=(0, 0))
    assert bounding_box(bp.zones == DIG) == (0, 1, 0, 1)
    expected_dump = np.zeros((6, 6), dtype=bool)
    expected_dump[0:4, 0:4] = True
    expected_dump[0:2, 0:2] = False
    assert np.array_equal(bp.zones == DUMP, expected_dump)
    assert np.all(bp.zones[4:, :] == DONT_CARE)
    assert np.all(bp.zones[:, 4:] == DONT_CARE)


def test_pit_blueprint_filling_the_whole_grid() -> None:
    bp = pit_blueprint(grid=(3, 4), pit_size=(3, 4), depth=2, dump_band=3)
    assert bp.dig_cells == 12
    assert np.all(bp.goal == -2)


@pytest.mark.parametrize(
    "origin",
    [(9, 0), (0, 9), (-1, 4), (4, -1), (15, 15)],
)
def test_pit_blueprint_pit_leaving_the_grid(origin: tuple[int, int]) -> None:
    with pytest.raises(BlueprintError, match=r"pit\.origin") as info:
        pit_blueprint(grid=(16, 16), pit_size=(8, 8), origin=origin)
    assert info.value.field == "pit.origin"
    assert info.value.value == list(origin)
    assert "16 x 16" in info.value.reason


def test_pit_blueprint_pit_larger_than_grid() -> None:
    with pytest.raises(BlueprintError) as info:
        pit_blueprint(grid=(4, 4), pit_size=(5, 2))
    assert info.value.field == "pit.origin"


@pytest.mark.parametrize("depth", [0, -1])
def test_pit_blueprint_depth_must_be_positive(depth: int) -> None:
    with pytest.raises(BlueprintError, match=r"pit\.depth") as info:
        pit_blueprint(depth=depth)
    assert info.value.field == "pit.depth"
    assert info.value.value == depth


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"grid": (0, 5)}, "grid"),
        ({"grid": (5, -2)}, "grid"),
        ({"pit_size": (0, 3)}, "pit.size"),
        ({"dump_band": -1}, "dump_band"),
    ],
)
def test_pit_blueprint_bad_sizes(kwargs: dict, field: str) -> None:
    with pytest.raises(BlueprintError) as info:
        pit_blueprint(**kwargs)
    assert info.value.field == field


# --- 3. landing pad -------------------------------------------------------------------------


def test_landing_pad_default_cells() -> None:
    bp = landing_pad()
    assert bp.cell_size == 0.5
    assert bp.height_unit == 0.25
    # margin 2 + band 2 + ramp 7 + pad 18 + band 2 + margin 2; margin 2 + band 2 + pad 21 + ...
    assert bp.shape == (33, 29)

    pad = bp.goal == -8
    ramp = bp.goal == -4
    assert int(np.count_nonzero(pad)) == 18 * 21
    assert int(np.count_nonzero(ramp)) == 7 * 10
    assert bp.dig_cells == 18 * 21 + 7 * 10
    assert sorted(np.unique(bp.goal).tolist()) == [-8, -4, 0]

    pr0, pr1, pc0, pc1 = bounding_box(pad)
    rr0, rr1, rc0, rc1 = bounding_box(ramp)
    assert (pr1 - pr0 + 1, pc1 - pc0 + 1) == (18, 21)
    assert (rr1 - rr0 + 1, rc1 - rc0 + 1) == (7, 10)
    assert (pr0, pc0) == (11, 4)
    assert (rr0, rc0) == (4, 9)
    # Ramp south of the pad (smaller rows), touching its southern edge, inside its columns.
    assert rr1 < pr0
    assert rr1 + 1 == pr0
    assert pc0 < rc0 and rc1 < pc1
    # Ramp in the middle of the pad's edge (within a cell).
    assert abs((rc0 - pc0) - (pc1 - rc1)) <= 1


@pytest.mark.parametrize("cell_size", [0.5, 0.25])
def test_landing_pad_dump_band_surrounds_pad_and_ramp(cell_size: float) -> None:
    bp = landing_pad(cell_size=cell_size)
    band = round(1.0 / cell_size)
    dig = bp.zones == DIG
    expected_used = dilate(dig, band)
    assert np.array_equal(bp.zones != DONT_CARE, expected_used)
    assert np.array_equal(bp.zones == DUMP, expected_used & ~dig)
    # The 1 m don't-care margin keeps the band off the edges of the grid.
    margin = round(1.0 / cell_size)
    assert np.all(bp.zones[:margin, :] == DONT_CARE)
    assert np.all(bp.zones[-margin:, :] == DONT_CARE)
    assert np.all(bp.zones[:, :margin] == DONT_CARE)
    assert np.all(bp.zones[:, -margin:] == DONT_CARE)
    assert np.any(bp.zones[margin, :] == DUMP)


def test_landing_pad_quarter_metre_cells_double_the_dimensions() -> None:
    bp = landing_pad(cell_size=0.25)
    assert bp.shape == (66, 58)
    pad = bp.goal == -8
    ramp = bp.goal == -4
    assert int(np.count_nonzero(pad)) == 36 * 42
    assert int(np.count_nonzero(ramp)) == 14 * 20
    pr0, pr1, pc0, pc1 = bounding_box(pad)
    rr0, rr1, rc0, rc1 = bounding_box(ramp)
    assert (pr1 - pr0 + 1, pc1 - pc0 + 1) == (36, 42)
    assert (rr1 - rr0 + 1, rc1 - rc0 + 1) == (14, 20)
    assert rr1 + 1 == pr0
    assert pc0 < rc0 and rc1 < pc1


def test_landing_pad_height_unit_sets_depths() -> None:
    bp = landing_pad(height_unit=0.5)
    assert int(np.count_nonzero(bp.goal == -4)) == 18 * 21
    assert int(np.count_nonzero(bp.goal == -2)) == 7 * 10


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"cell_size": 0.0}, "cell_size"),
        ({"cell_size": -0.5}, "cell_size"),
        ({"cell_size": math.nan}, "cell_size"),
        ({"height_unit": math.inf}, "height_unit"),
        ({"cell_size": 50.0}, "pad.length"),
    ],
)
def test_landing_pad_bad_arguments(kwargs: dict, field: str) -> None:
    with pytest.raises(BlueprintError) as info:
        landing_pad(**kwargs)
    assert info.value.field == field


# --- 4. parametric YAML ---------------------------------------------------------------------


def test_parametric_yaml_equals_pit_blueprint(tmp_path: Path) -> None:
    path = write(
        tmp_path,
        "pit.yaml",
        f"""\
format: {FORMAT}
cell_size: 0.5
height_unit: 0.1
grid: [12, 20]
pit:
  size: [3, 6]
  depth: 3
  origin: [1, 10]
dump_band: 1
""",
    )
    bp = load_blueprint(path)
    expected = pit_blueprint(
        grid=(12, 20),
        pit_size=(3, 6),
        depth=3,
        dump_band=1,
        origin=(1, 10),
        cell_size=0.5,
        height_unit=0.1,
    )
    assert bp == expected
    assert bp.shape == (12, 20)
    assert bp.cell_size == 0.5
    assert bp.height_unit == 0.1
    assert bounding_box(bp.zones == DIG) == (1, 3, 10, 15)
    assert np.all(bp.goal[1:4, 10:16] == -3)
    assert bp.name == str(path)
    assert bp != default_blueprint(3)


def test_parametric_yaml_defaults_are_the_default_blueprint(tmp_path: Path) -> None:
    path = write(tmp_path, "d.yaml", f"format: {FORMAT}\npit: {{}}\n")
    assert load_blueprint(path) == default_blueprint(1)
    path = write(tmp_path, "d2.yaml", f"format: {FORMAT}\npit: {{depth: 2}}\n")
    assert load_blueprint(path) == default_blueprint(2)


def test_blueprint_from_dict_parametric() -> None:
    data = {"format": FORMAT, "grid": [8, 8], "pit": {"size": [2, 2], "depth": 5}}
    bp = blueprint_from_dict(data)
    assert bp == pit_blueprint((8, 8), (2, 2), 5)
    assert bp.name == "<memory>"


def test_parametric_pit_leaving_grid_names_the_file(tmp_path: Path) -> None:
    path = write(
        tmp_path,
        "off.yaml",
        f"format: {FORMAT}\ngrid: [10, 10]\npit: {{size: [4, 4], origin: [8, 0]}}\n",
    )
    with pytest.raises(BlueprintError, match=r"pit\.origin") as info:
        load_blueprint(path)
    assert info.value.field == "pit.origin"
    assert info.value.value == [8, 0]
    assert_error_names_file(info.value, path)


def test_parametric_depth_zero_names_the_file(tmp_path: Path) -> None:
    path = write(tmp_path, "zero.yaml", f"format: {FORMAT}\npit: {{depth: 0}}\n")
    with pytest.raises(BlueprintError, match=r"pit\.depth") as info:
        load_blueprint(path)
    assert info.value.field == "pit.depth"
    assert info.value.value == 0
    assert_error_names_file(info.value, path)


# --- 5. per-cell YAML -----------------------------------------------------------------------


def test_per_cell_rows_are_north_first(tmp_path: Path) -> None:
    path = write(
        tmp_path,
        "cells.yaml",
        f"""\
format: {FORMAT}
cell_size: 0.5
height_unit: 0.2
rows:
  - ".2.D"
  - "D..."
  - "13.."
""",
    )
    bp = load_blueprint(path)
    assert bp.shape == (3, 4)
    assert bp.cell_size == 0.5
    assert bp.height_unit == 0.2
    # First line -> highest row index (north).
    assert bp.zones[2, 1] == DIG
    assert bp.goal[2, 1] == -2
    assert bp.zones[2, 3] == DUMP
    assert bp.zones[1, 0] == DUMP
    assert bp.zones[0, 0] == DIG and bp.goal[0, 0] == -1
    assert bp.zones[0, 1] == DIG and bp.goal[0, 1] == -3
    assert bp.zones.tolist() == [
        [DIG, DIG, DONT_CARE, DONT_CARE],
        [DUMP, DONT_CARE, DONT_CARE, DONT_CARE],
        [DONT_CARE, DIG, DONT_CARE, DUMP],
    ]
    assert bp.goal.tolist() == [[-1, -3, 0, 0], [0, 0, 0, 0], [0, -2, 0, 0]]
    assert bp.to_rows() == [".2.D", "D...", "13.."]


def test_per_cell_defaults(tmp_path: Path) -> None:
    path = write(tmp_path, "c.yaml", f"format: {FORMAT}\nrows: ['9']\n")
    bp = load_blueprint(path)
    assert bp.cell_size == 0.25
    assert bp.height_unit == 0.05
    assert bp.goal.tolist() == [[-9]]


def test_to_rows_of_default_blueprint() -> None:
    rows = default_blueprint(2).to_rows()
    assert len(rows) == 16
    assert all(len(r) == 16 for r in rows)
    assert rows[0] == "." * 16
    assert rows[2] == "..DDDDDDDDDDDD.."
    assert rows[4] == "..DD22222222DD.."
    assert rows[11] == "..DD22222222DD.."
    assert rows[13] == "..DDDDDDDDDDDD.."
    assert rows[15] == "." * 16


@pytest.mark.parametrize(
    "bp",
    [
        default_blueprint(2),
        landing_pad(),
        landing_pad(cell_size=0.25),
        pit_blueprint((5, 7), (2, 3), 9, 1, origin=(3, 0), cell_size=0.4, height_unit=0.125),
    ],
    ids=["default2", "landing_pad", "landing_pad_0.25", "pit_north_west"],
)
def test_to_yaml_round_trip(tmp_path: Path, bp: Blueprint) -> None:
    path = write(tmp_path, "rt.yaml", bp.to_yaml())
    loaded = load_blueprint(path)
    assert loaded == bp
    assert loaded.shape == bp.shape
    assert loaded.dig_cells == bp.dig_cells
    assert loaded.to_rows() == bp.to_rows()


@pytest.mark.parametrize(
    "bp",
    [
        pit_blueprint((3, 3), (1, 1), depth=12, dump_band=0),
        pit_blueprint((1, 2), (1, 1), depth=12, dump_band=0),
    ],
    ids=["unloadable", "loads_as_another_blueprint"],
)
def test_to_yaml_round_trip_with_depth_of_ten_or_more(tmp_path: Path, bp: Blueprint) -> None:
    # to_yaml() promises output loadable by load_blueprint. A goal of 10 or more soil units
    # cannot be written as one character: refusing to write it is acceptable, writing a
    # file that loads as a different (or broken) blueprint is not.
    try:
        text = bp.to_yaml()
    except ValueError:
        return
    path = write(tmp_path, "deep.yaml", text)
    assert load_blueprint(path) == bp


# --- 6. image form --------------------------------------------------------------------------

BGR = {
    ".": (255, 255, 255),
    "D": (0, 255, 0),
    "3": (0, 0, 0),
    "2": (85, 85, 85),
}
ART = [  # top of the image first = north first
    ".D3332D.",
    ".D3332D.",
    ".DDDDDD.",
    "........",
    "........",
    "........",
]


def paint(art: list[str], px: int) -> np.ndarray:
    image = np.zeros((len(art) * px, len(art[0]) * px, 3), dtype=np.uint8)
    for i, line in enumerate(art):
        for j, ch in enumerate(line):
            image[i * px : (i + 1) * px, j * px : (j + 1) * px] = BGR[ch]
    return image


def test_image_form(tmp_path: Path) -> None:
    assert cv2.imwrite(str(tmp_path / "site.png"), paint(ART, 5))
    path = write(
        tmp_path,
        "site.yaml",
        f"format: {FORMAT}\ncell_size: 0.25\nheight_unit: 0.1\nimage: site.png\nscale: 0.05\n",
    )
    bp = load_blueprint(path)
    assert bp.shape == (6, 8)
    assert bp.cell_size == 0.25
    assert bp.height_unit == 0.1
    # Top of the image is north: the highest row index.
    assert bp.zones[5].tolist() == [0, 2, 1, 1, 1, 1, 2, 0]
    assert bp.goal[5].tolist() == [0, 0, -3, -3, -3, -2, 0, 0]
    assert bp.zones[4].tolist() == [0, 2, 1, 1, 1, 1, 2, 0]
    assert bp.goal[4].tolist() == [0, 0, -3, -3, -3, -2, 0, 0]
    assert bp.zones[3].tolist() == [0, 2, 2, 2, 2, 2, 2, 0]
    assert np.all(bp.zones[:3] == DONT_CARE)
    assert bp.dig_cells == 8
    # Same as the per-cell drawing of the same picture.
    rows_path = write(
        tmp_path,
        "rows.yaml",
        f"format: {FORMAT}\ncell_size: 0.25\nheight_unit: 0.1\nrows: {ART!r}\n",
    )
    assert bp == load_blueprint(rows_path)


def test_image_form_max_depth_and_absolute_image_path(tmp_path: Path) -> None:
    image_path = tmp_path / "img" / "pit.png"
    image_path.parent.mkdir()
    assert cv2.imwrite(str(image_path), paint(["3.", "2D"], 4))
    sub = tmp_path / "yaml"
    sub.mkdir()
    path = write(
        sub,
        "abs.yaml",
        f"format: {FORMAT}\ncell_size: 1.0\nheight_unit: 0.5\n"
        f"image: {image_path}\nscale: 0.25\nmax_depth: 3.0\n",
    )
    bp = load_blueprint(path)
    assert bp.shape == (2, 2)
    # black = 3.0 m = 6 units; gray 85 = 2.0 m = 4 units
    assert bp.zones.tolist() == [[DIG, DUMP], [DIG, DONT_CARE]]
    assert bp.goal.tolist() == [[-4, 0], [-6, 0]]


def test_from_image_majority_and_minimum_depth(tmp_path: Path) -> None:
    image = np.full((10, 20, 3), 255, dtype=np.uint8)
    # Cell (image top-left, 10 x 10 px): 6 green rows over 4 white rows -> dump.
    image[0:6, 0:10] = (0, 255, 0)
    # Cell (image top-right): 6 rows very light gray (depth rounds to 0 -> at least 1).
    image[0:6, 10:20] = (240, 240, 240)
    path = tmp_path / "m.png"
    assert cv2.imwrite(str(path), image)
    bp = from_image(path, scale=0.1, cell_size=1.0, height_unit=0.1)
    assert bp.shape == (1, 2)
    assert bp.zones.tolist() == [[DUMP, DIG]]
    assert bp.goal.tolist() == [[0, -1]]
    assert bp.name == str(path)


def test_image_form_missing_scale(tmp_path: Path) -> None:
    assert cv2.imwrite(str(tmp_path / "site.png"), paint(ART, 5))
    path = write(tmp_path, "noscale.yaml", f"format: {FORMAT}\nimage: site.png\n")
    with pytest.raises(BlueprintError, match="scale") as info:
        load_blueprint(path)
    assert info.value.field == "scale"
    assert_error_names_file(info.value, path)


@pytest.mark.parametrize("scale", ["0", "-0.1", ".nan", "big"])
def test_image_form_bad_scale(tmp_path: Path, scale: str) -> None:
    assert cv2.imwrite(str(tmp_path / "site.png"), paint(ART, 5))
    path = write(tmp_path, "bad.yaml", f"format: {FORMAT}\nimage: site.png\nscale: {scale}\n")
    with pytest.raises(BlueprintError) as info:
        load_blueprint(path)
    assert info.value.field == "scale"
    assert_error_names_file(info.value, path)


def test_image_smaller_than_a_cell(tmp_path: Path) -> None:
    assert cv2.imwrite(str(tmp_path / "tiny.png"), paint(["3"], 2))
    with pytest.raises(BlueprintError) as info:
        from_image(tmp_path / "tiny.png", scale=0.01, cell_size=0.25)
    assert info.value.field == "scale"


@pytest.mark.parametrize("make_file", [True, False], ids=["garbage", "missing"])
def test_image_form_unreadable_image(tmp_path: Path, make_file: bool) -> None:
    if make_file:
        (tmp_path / "broken.png").write_bytes(b"this is not a png")
    path = write(tmp_path, "img.yaml", f"format: {FORMAT}\nimage: broken.png\nscale: 0.05\n")
    with pytest.raises(BlueprintError, match="is not a PNG|does not exist") as info:
        load_blueprint(path)
    assert info.value.field == "image"
    assert "broken.png" in str(info.value)


def test_image_form_image_not_a_string(tmp_path: Path) -> None:
    path = write(tmp_path, "img.yaml", f"format: {FORMAT}\nimage: [a, b]\nscale: 0.05\n")
    with pytest.raises(BlueprintError) as info:
        load_blueprint(path)
    assert info.value.field == "image"
    assert_error_names_file(info.value, path)


# --- 7. bad files ---------------------------------------------------------------------------

BAD_FILES = [
    # (id, text, field, match)
    ("invalid_yaml", f"format: {FORMAT}\nrows: ['1.', '2.'\n", None, "not valid YAML"),
    ("root_list", "- 1\n- 2\n", "<root>", "must be a mapping"),
    ("root_scalar", "just a string\n", "<root>", "must be a mapping"),
    ("empty_file", "", "<root>", "must be a mapping"),
    ("wrong_format", "format: ant-blueprint/2\npit: {}\n", "format", "ant-blueprint/1"),
    ("missing_format", "pit: {}\n", "format", "ant-blueprint/1"),
    ("unknown_top_key", f"format: {FORMAT}\npit: {{}}\ncolour: red\n", "colour", "unknown key"),
    ("rows_with_grid", f"format: {FORMAT}\ngrid: [1, 2]\nrows: ['11']\n", "grid", "unknown key"),
    ("unknown_pit_key", f"format: {FORMAT}\npit: {{width: 3}}\n", "pit.width", "unknown key"),
    ("pit_not_mapping", f"format: {FORMAT}\npit: [8, 8]\n", "pit", "mapping"),
    ("rows_unequal", f"format: {FORMAT}\nrows: ['1..', '1.', '...']\n", "rows[1]", "cells"),
    ("rows_bad_char", f"format: {FORMAT}\nrows: ['11x', '...']\n", "rows[0][2]", "use '.'"),
    ("rows_zero", f"format: {FORMAT}\nrows: ['...', '.0.']\n", "rows[1][1]", "use '.'"),
    ("rows_lower_d", f"format: {FORMAT}\nrows: ['d']\n", "rows[0][0]", "use '.'"),
    ("rows_empty", f"format: {FORMAT}\nrows: []\n", "rows", "non-empty list"),
    ("rows_not_strings", f"format: {FORMAT}\nrows: [111, 222]\n", "rows", "list of strings"),
    ("cell_size_negative", f"format: {FORMAT}\ncell_size: -0.5\npit: {{}}\n", "cell_size", "pos"),
    ("cell_size_zero", f"format: {FORMAT}\ncell_size: 0\npit: {{}}\n", "cell_size", "positive"),
    ("cell_size_nan", f"format: {FORMAT}\ncell_size: .nan\npit: {{}}\n", "cell_size", "finite"),
    ("cell_size_inf", f"format: {FORMAT}\ncell_size: .inf\npit: {{}}\n", "cell_size", "finite"),
    ("cell_size_str", f"format: {FORMAT}\ncell_size: 'nan'\npit: {{}}\n", "cell_size", "finite"),
    ("cell_size_bool", f"format: {FORMAT}\ncell_size: true\npit: {{}}\n", "cell_size", "finite"),
    ("height_unit_neg", f"format: {FORMAT}\nheight_unit: -1\npit: {{}}\n", "height_unit", "pos"),
    ("grid_triple", f"format: {FORMAT}\ngrid: [16, 16, 16]\npit: {{}}\n", "grid", "two integers"),
    ("grid_scalar", f"format: {FORMAT}\ngrid: 16\npit: {{}}\n", "grid", "two integers"),
    ("grid_floats", f"format: {FORMAT}\ngrid: [16.0, 16]\npit: {{}}\n", "grid", "two integers"),
    ("grid_zero", f"format: {FORMAT}\ngrid: [0, 16]\npit: {{}}\n", "grid", "positive"),
    ("size_single", f"format: {FORMAT}\npit: {{size: [4]}}\n", "pit.size", "two integers"),
    ("origin_str", f"format: {FORMAT}\npit: {{origin: 'a,b'}}\n", "pit.origin", "two integers"),
    ("depth_float", f"format: {FORMAT}\npit: {{depth: 1.5}}\n", "pit.depth", "integer"),
    ("depth_string", f"format: {FORMAT}\npit: {{depth: '2'}}\n", "pit.depth", "integer"),
    ("depth_bool", f"format: {FORMAT}\npit: {{depth: true}}\n", "pit.depth", "integer"),
    ("dump_band_float", f"format: {FORMAT}\npit: {{}}\ndump_band: 1.5\n", "dump_band", "integer"),
    ("dump_band_neg", f"format: {FORMAT}\npit: {{}}\ndump_band: -1\n", "dump_band", "0 or more"),
    ("two_forms", f"format: {FORMAT}\npit: {{}}\nrows: ['1']\n", "rows|pit|image", "exactly one"),
    ("three_forms", f"format: {FORMAT}\npit: {{}}\nrows: ['1']\nimage: a.png\n", None, "one"),
    ("no_form", f"format: {FORMAT}\ncell_size: 0.5\n", "rows|pit|image", "exactly one"),
]


@pytest.mark.parametrize(
    ("text", "field", "match"),
    [case[1:] for case in BAD_FILES],
    ids=[case[0] for case in BAD_FILES],
)
def test_bad_files(tmp_path: Path, text: str, field: str | None, match: str) -> None:
    path = write(tmp_path, "bad.yaml", text)
    with pytest.raises(BlueprintError, match=re.escape(match)) as info:
        load_blueprint(path)
    exc = info.value
    if field is not None:
        assert exc.field == field
    assert_error_names_file(exc, path)
    assert str(exc).startswith(f"{path}: {exc.field} = {exc.value!r}: ")


def test_invalid_yaml_names_the_line(tmp_path: Path) -> None:
    path = write(tmp_path, "bad.yaml", f"format: {FORMAT}\nrows: [a, b\n")
    with pytest.raises(BlueprintError, match="is not valid YAML") as info:
        load_blueprint(path)
    assert re.fullmatch(r"line \d+", info.value.field)
    assert info.value.value is None
    assert_error_names_file(info.value, path)


def test_missing_file(tmp_path: Path) -> None:
    path = tmp_path / "nowhere.yaml"
    with pytest.raises(BlueprintError, match="does not exist") as info:
        load_blueprint(path)
    assert info.value.field == "<file>"
    assert info.value.value == str(path)
    assert_error_names_file(info.value, path)


def test_directory_instead_of_file(tmp_path: Path) -> None:
    with pytest.raises(BlueprintError, match="cannot be read") as info:
        load_blueprint(tmp_path)
    assert info.value.field == "<file>"
    assert_error_names_file(info.value, tmp_path)


def test_not_utf8_file(tmp_path: Path) -> None:
    path = tmp_path / "latin1.yaml"
    path.write_bytes(b"format: \xff\xfe\n")
    with pytest.raises(BlueprintError, match="cannot be read") as info:
        load_blueprint(path)
    assert info.value.field == "<file>"


def test_specific_error_values(tmp_path: Path) -> None:
    path = write(tmp_path, "u.yaml", f"format: {FORMAT}\nrows: ['1..', '1.', '...']\n")
    with pytest.raises(BlueprintError) as info:
        load_blueprint(path)
    assert info.value.value == "1."
    assert info.value.reason == "has 2 cells, row 0 has 3"

    path = write(tmp_path, "c.yaml", f"format: {FORMAT}\nrows: ['11x', '...']\n")
    with pytest.raises(BlueprintError) as info:
        load_blueprint(path)
    assert info.value.value == "x"
    assert str(info.value) == (
        f"{path}: rows[0][2] = 'x': use '.' don't care, 'D' dump, '1'-'9' dig depth"
    )

    path = write(tmp_path, "f.yaml", f"format: {FORMAT}\npit: {{}}\nrows: ['1']\n")
    with pytest.raises(BlueprintError) as info:
        load_blueprint(path)
    assert info.value.value == ["rows", "pit"]

    path = write(tmp_path, "n.yaml", f"format: {FORMAT}\ncell_size: .nan\npit: {{}}\n")
    with pytest.raises(BlueprintError) as info:
        load_blueprint(path)
    assert math.isnan(info.value.value)


def test_rows_with_non_ascii_digit_raise_blueprint_error(tmp_path: Path) -> None:
    # Documented: '1'-'9' dig depth, anything else is a BlueprintError naming the cell.
    # '\u00b2' (superscript two) passes str.isdigit() but int() rejects it.
    path = write(tmp_path, "sup.yaml", f"format: {FORMAT}\nrows: ['1\u00b2']\n")
    with pytest.raises(BlueprintError) as info:
        load_blueprint(path)
    assert info.value.field == "rows[0][1]"
    assert_error_names_file(info.value, path)


def test_resolve_blueprint(tmp_path: Path) -> None:
    assert resolve_blueprint(None) == default_blueprint(1)
    assert resolve_blueprint("default", depth=3) == default_blueprint(3)
    path = write(tmp_path, "r.yaml", f"format: {FORMAT}\nrows: ['D2']\n")
    bp = resolve_blueprint(str(path))
    assert bp.goal.tolist() == [[0, -2]]
    with pytest.raises(BlueprintError):
        resolve_blueprint(str(tmp_path / "missing.yaml"))


# --- 8. blueprint_info CLI ------------------------------------------------------------------


def test_cli_default_depth_two(capsys: pytest.CaptureFixture[str]) -> None:
    assert blueprint_info.main(["default:2"]) == 0
    out = capsys.readouterr().out
    assert "16 rows x 16 cols" in out
    assert "dig cells 64" in out
    assert "dump cells 80" in out
    assert "goal depths [2]" in out


def test_cli_default_and_landing_pad(capsys: pytest.CaptureFixture[str]) -> None:
    assert blueprint_info.main(["default"]) == 0
    out = capsys.readouterr().out
    assert "dig cells 64" in out and "goal depths [1]" in out
    assert blueprint_info.main(["landing-pad"]) == 0
    out = capsys.readouterr().out
    assert "33 rows x 29 cols" in out
    assert f"dig cells {18 * 21 + 7 * 10}" in out
    assert "goal depths [4, 8]" in out


@pytest.mark.parametrize("spec", ["default:0", "default:x", "default:-1"])
def test_cli_bad_default_depth(capsys: pytest.CaptureFixture[str], spec: str) -> None:
    assert blueprint_info.main([spec]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert "depth" in captured.err


def test_cli_rows_prints_loadable_yaml(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert blueprint_info.main(["default:3", "--rows"]) == 0
    out = capsys.readouterr().out
    text = out[out.index("format:") :]
    path = write(tmp_path, "out.yaml", text)
    assert load_blueprint(path) == default_blueprint(3)


def test_cli_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write(tmp_path, "ok.yaml", f"format: {FORMAT}\nrows: ['.D', '31']\n")
    assert blueprint_info.main([str(path)]) == 0
    out = capsys.readouterr().out
    assert "2 rows x 2 cols" in out
    assert "dig cells 2, dump cells 1" in out
    assert "goal depths [1, 3]" in out


def test_cli_bad_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write(tmp_path, "bad.yaml", f"format: {FORMAT}\nrows: ['1..', '1.']\n")
    assert blueprint_info.main([str(path)]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert "error" in captured.err
    assert str(path) in captured.err
    assert "rows[1]" in captured.err


def test_cli_missing_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "absent.yaml"
    assert blueprint_info.main([str(path)]) == 2
    assert str(path) in capsys.readouterr().err


def test_cli_png(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    png = tmp_path / "lp.png"
    assert blueprint_info.main(["landing-pad", "--png", str(png)]) == 0
    assert png.is_file()
    data = png.read_bytes()
    assert len(data) > 1000
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    image = cv2.imread(str(png))
    assert image is not None and image.shape[2] == 3
    assert f"wrote {png}" in capsys.readouterr().out


# --- 8. limits (checked before any grid is allocated) ---------------------------------------


def test_grid_limits_before_allocation(monkeypatch: pytest.MonkeyPatch) -> None:
    from blueprint_server.limits import MAX_GRID_CELLS, MAX_GRID_SIDE

    def no_allocation(*args, **kwargs):
        raise AssertionError("allocated before the limit check")

    monkeypatch.setattr(np, "zeros", no_allocation)
    with pytest.raises(BlueprintError, match=f"limit of {MAX_GRID_SIDE} cells a side"):
        pit_blueprint((MAX_GRID_SIDE + 1, 16), (8, 8))
    with pytest.raises(BlueprintError, match=f"more than the limit of {MAX_GRID_CELLS}"):
        pit_blueprint((2048, 2048), (8, 8))
    with pytest.raises(BlueprintError, match="pit.depth"):
        pit_blueprint((16, 16), (8, 8), depth=10**20)
    with pytest.raises(BlueprintError, match="limit of 4096 cells a side"):
        landing_pad(cell_size=0.001)  # 16,500 cells long


def test_largest_grid_and_depth_are_accepted() -> None:
    from blueprint_server.limits import MAX_DEPTH_UNITS

    bp = pit_blueprint((1024, 1024), (8, 8), depth=MAX_DEPTH_UNITS)
    assert bp.shape == (1024, 1024)
    assert int(bp.goal.min()) == -MAX_DEPTH_UNITS
    assert resolve_blueprint(f"default:{MAX_DEPTH_UNITS}").goal.min() == -MAX_DEPTH_UNITS
    with pytest.raises(BlueprintError, match="the limit"):
        resolve_blueprint(f"default:{MAX_DEPTH_UNITS + 1}")


def test_blueprint_file_size_limit(tmp_path: Path) -> None:
    from blueprint_server.limits import MAX_BLUEPRINT_BYTES

    path = tmp_path / "big.yaml"
    with path.open("wb") as f:
        f.truncate(MAX_BLUEPRINT_BYTES + 1)  # sparse: costs no disk
    with pytest.raises(BlueprintError, match=f"limit of {MAX_BLUEPRINT_BYTES} bytes") as info:
        load_blueprint(path)
    assert info.value.field == "<file>"


def test_image_header_checked_before_decoding(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    corpus = Path(__file__).parent / "data" / "broken" / "blueprint"

    def no_decode(*args, **kwargs):
        raise AssertionError("decoded before the header check")

    monkeypatch.setattr(cv2, "imread", no_decode)
    with pytest.raises(BlueprintError, match="20000 x 20000") as info:
        from_image(corpus / "huge_image.png", scale=0.05)
    assert info.value.field == "image"
    # Cells smaller than pixels: a 64 x 64 image at 1 mm per pixel in 0.001 m cells is fine,
    # but at 1 m per pixel it would make 64,000 x 64,000 cells.
    with pytest.raises(BlueprintError, match="limit of 4096 cells a side"):
        from_image(corpus / "ok_image.png", scale=1.0, cell_size=0.001, height_unit=0.001)


def test_duplicate_key_is_refused(tmp_path: Path) -> None:
    path = write(tmp_path, "dup.yaml", f"format: {FORMAT}\npit: {{size: [8, 8]}}\npit: {{}}\n")
    with pytest.raises(BlueprintError, match="given twice") as info:
        load_blueprint(path)
    assert info.value.field == "pit"
