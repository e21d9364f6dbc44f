"""Broken and hostile inputs give one clear line and exit code 2, never a traceback.

Every file of the corpus in ``tests/data/broken/`` (rebuilt by its ``make_corpus.py``) is
handed to each command line that reads that kind of file, in a subprocess with its address
space capped at 2 GiB and a timeout: a limit that is checked only after allocating, or an
image decoded before its header is checked, ends in a MemoryError or the timeout instead.
The message must name the file, the field and the limit (``EXPECT``). Then the loaders
themselves (``excavation_common.loaders``) and the hostile command-line numbers.
"""

from __future__ import annotations

import resource
import subprocess
import sys
from pathlib import Path

import pytest

from excavation_common.errors import FieldError
from excavation_common.limits import INT32_MAX, MAX_DEPTH_UNITS, MAX_GRID_CELLS
from excavation_common.loaders import (
    check_image,
    image_size,
    load_json,
    load_yaml,
    parse_json,
    parse_yaml,
    read_text_bounded,
)

ROOT = Path(__file__).resolve().parents[1]
CORPUS = ROOT / "tests" / "data" / "broken"
BIN = Path(sys.executable).parent
MEMORY_LIMIT = 2 << 30
TIMEOUT = 120

# File (relative to the corpus) -> fragments its error line must contain: the field and the
# limit or the rule broken. Every file of the corpus has an entry (test_corpus_is_described).
EXPECT: dict[str, tuple[str, ...]] = {
    "blueprint/alias_bomb.yaml": ("*a", "aliases are not allowed"),
    "blueprint/deep_nesting.yaml": ("line 2", "limit of 32 levels"),
    "blueprint/duplicate_key.yaml": ("grid", "given twice"),
    "blueprint/duplicate_nested_key.yaml": ("depth", "given twice"),
    "blueprint/garbage.yaml": ("<file>", "not UTF-8"),
    "blueprint/huge_cells.yaml": ("grid", "limit of 1048576"),
    "blueprint/huge_depth.yaml": ("pit.depth", "1..500"),
    "blueprint/huge_dump_band.yaml": ("dump_band", "at most 16"),
    "blueprint/huge_float.yaml": ("height_unit", "finite"),
    "blueprint/huge_grid.yaml": ("grid = [100000000, 100000000]", "limit of 4096"),
    "blueprint/huge_image.yaml": ("image", "20000 x 20000", "limit of 16384", "huge_image.png"),
    "blueprint/huge_image_depth.yaml": ("max_depth", "500 soil units"),
    "blueprint/huge_pit.yaml": ("pit.size", "limit of 4096"),
    "blueprint/not_an_image.yaml": ("image", "not a PNG, JPEG or BMP"),
    "blueprint/tiny_cell_size.yaml": ("cell_size", "0.001..100.0"),
    "blueprint/truncated.yaml": ("line 3", "not valid YAML"),
    "blueprint/wide_rows.yaml": ("rows", "limit of 4096"),
    "genome/deep_nesting.json": ("<json>", "limit of 32 levels"),
    "genome/duplicate_key.json": ("format", "given twice"),
    "genome/garbage.json": ("<file>", "not UTF-8"),
    "genome/huge_float.json": ("1e999", "64-bit float"),
    "genome/huge_gene_count.json": ("cells", "limit of 10000 genes"),
    "genome/huge_integer.json": ("<json>", "4300 digits"),
    "genome/huge_robots_gene.json": ("tissue.robots", "1..64"),
    "genome/nan.json": ("NaN", "not allowed"),
    "genome/truncated.json": ("line 127", "not valid JSON"),
    "config/broken_blueprint.yaml": ("huge_grid.yaml", "grid", "limit of 4096"),
    "config/duplicate_key.yaml": ("population", "given twice"),
    "config/garbage.yaml": ("<file>", "not UTF-8"),
    "config/huge_depths.yaml": ("depths[2]", "1..500"),
    "config/huge_population.yaml": ("population", "2..10000"),
    "config/huge_steps.yaml": ("steps", "1..100000"),
    "config/huge_workload.yaml": ("population x scenarios", "limit of 134217728"),
    "config/negative_seed.yaml": ("seed = -1", "0..9223372036854775807"),
    "config/unknown_key.yaml": ("populaton", "not a known key"),
    "localizer/beacons_duplicate_key.yaml": ("height", "given twice"),
    "localizer/beacons_garbage.yaml": ("<file>", "not UTF-8"),
    "localizer/beacons_too_many_robots.yaml": ("robots", "limit of 64"),
    "localizer/camera_duplicate_key.yaml": ("rms_px", "given twice"),
    "localizer/camera_huge_image.yaml": ("image_width", "limit of 16384"),
    "localizer/camera_truncated.yaml": ("not valid YAML",),
    "localizer/marks_deep_nesting.yaml": ("limit of 32 levels",),
    "localizer/marks_duplicate_key.yaml": ("image_width", "given twice"),
    "map/garbage.npy": ("header", "not a .npy header"),
    "map/huge_shape.npy": ("shape", "[100000, 100000]", "1048576 cells"),
}
# Files that are parts of other cases (an image a blueprint names), not cases themselves.
PARTS = {"blueprint/huge_image.png", "blueprint/not_an_image.png", "blueprint/ok_image.png"}


def corpus(kind: str, pattern: str) -> list[str]:
    """Corpus files of one kind (folder) matching a glob pattern, relative to the corpus."""
    return sorted(str(p.relative_to(CORPUS)) for p in (CORPUS / kind).glob(pattern))


def _limit_memory() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))


def run(*argv: str, cwd: Path = ROOT) -> subprocess.CompletedProcess:
    """A console script of the venv, memory-capped, with a timeout."""
    return subprocess.run(
        [str(BIN / argv[0]), *argv[1:]],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=TIMEOUT,
        preexec_fn=_limit_memory,
        check=False,
    )


def assert_refused(done: subprocess.CompletedProcess, name: str, fragments: tuple[str, ...]):
    """Exit code 2, one line on stderr naming the file and every fragment, no traceback."""
    err = done.stderr
    assert "Traceback" not in err, err
    assert "MemoryError" not in err, err
    lines = [line for line in err.splitlines() if line.strip()]
    assert done.returncode == 2, (done.returncode, err)
    assert len(lines) == 1, err
    assert name in lines[0], lines[0]
    for fragment in fragments:
        assert fragment in lines[0], (fragment, lines[0])


def test_corpus_is_described() -> None:
    files = {str(p.relative_to(CORPUS)) for p in CORPUS.rglob("*") if p.is_file()}
    files -= {"make_corpus.py", "README.md"}
    assert files - PARTS == set(EXPECT)
    assert PARTS <= files


def test_soil_sums_fit_the_kernels_integer_type() -> None:
    # Every goal at the deepest depth on the largest grid, and a difference of two such sums.
    assert 2 * MAX_GRID_CELLS * MAX_DEPTH_UNITS < INT32_MAX


# --- every file through every command line that reads its kind ------------------------------


@pytest.mark.parametrize("rel", corpus("blueprint", "*.yaml"))
def test_blueprint_info(rel: str) -> None:
    assert_refused(run("blueprint_info", f"tests/data/broken/{rel}"), rel, EXPECT[rel])


@pytest.mark.parametrize("rel", corpus("blueprint", "*.yaml"))
def test_ant_eval_blueprint(rel: str) -> None:
    done = run(
        "ant-eval", "--hand-coded", "--blueprint", f"tests/data/broken/{rel}", "--scenarios", "1"
    )
    assert_refused(done, rel, EXPECT[rel])


@pytest.mark.parametrize("rel", corpus("genome", "*.json"))
def test_genome_info(rel: str) -> None:
    assert_refused(run("genome_info", f"tests/data/broken/{rel}"), rel, EXPECT[rel])


@pytest.mark.parametrize("rel", corpus("genome", "*.json"))
def test_ant_eval_genome(rel: str) -> None:
    done = run("ant-eval", "--genome", f"tests/data/broken/{rel}", "--scenarios", "1")
    assert_refused(done, rel, EXPECT[rel])


@pytest.mark.parametrize("rel", corpus("config", "*.yaml"))
def test_ant_evolve_config(rel: str, tmp_path: Path) -> None:
    done = run(
        "ant-evolve", "--config", f"tests/data/broken/{rel}", "--out", str(tmp_path), "--quiet"
    )
    name = "huge_grid.yaml" if rel == "config/broken_blueprint.yaml" else rel
    assert_refused(done, name, EXPECT[rel])


@pytest.mark.parametrize("rel", corpus("localizer", "*.yaml"))
def test_localizer_files(rel: str) -> None:
    from overhead_localizer.beacons import load_beacons
    from overhead_localizer.calibrate import load_marks
    from overhead_localizer.camera_model import load_model
    from overhead_localizer.errors import LocalizerConfigError

    loader = {"beacons": load_beacons, "camera": load_model, "marks": load_marks}
    with pytest.raises(LocalizerConfigError) as info:
        loader[Path(rel).name.split("_")[0]](str(CORPUS / rel))
    message = str(info.value)
    assert rel in message
    for fragment in EXPECT[rel]:
        assert fragment in message, (fragment, message)


@pytest.mark.parametrize("rel", corpus("localizer", "marks_*.yaml"))
def test_calibrate_marks(rel: str, tmp_path: Path) -> None:
    done = run("calibrate", f"tests/data/broken/{rel}", "--out", str(tmp_path / "c.yaml"))
    assert_refused(done, rel, EXPECT[rel])


@pytest.mark.parametrize("rel", corpus("map", "*.npy"))
def test_field_metrics(rel: str) -> None:
    path = f"tests/data/broken/{rel}"
    assert_refused(run("field-metrics", path, path), rel, EXPECT[rel])


# --- command-line numbers ---------------------------------------------------------------------

HOSTILE_OPTIONS = [
    ("ant-eval", "--hand-coded", "--robots", "1000"),
    ("ant-eval", "--hand-coded", "--robots", "-3"),
    ("ant-eval", "--hand-coded", "--scenarios", "99999999999"),
    ("ant-eval", "--hand-coded", "--steps", "0"),
    ("ant-eval", "--hand-coded", "--depth", "99999999999999999999"),
    ("ant-eval", "--hand-coded", "--seed", "-1"),
    ("ant-eval", "--hand-coded", "--snapshot-steps", "0,99999999999"),
    ("ant-evolve", "--out", "{tmp}", "--population", "100000000"),
    ("ant-evolve", "--out", "{tmp}", "--generations", "0"),
    ("ant-evolve", "--out", "{tmp}", "--workers", "100000"),
    ("ant-evolve", "--out", "{tmp}", "--robots-mix", "1,1000"),
    ("ant-evolve", "--out", "{tmp}", "--depths", "1,99999999"),
    ("ant-evolve", "--out", "{tmp}", "--domain-base", "9999"),
    ("ant-sweep", "--hand-coded", "--robots", "1-99999999", "--out", "{tmp}"),
    ("ant-sweep", "--hand-coded", "--steps", "-5", "--out", "{tmp}"),
    ("ant-experiment", "antagonism", "--workers", "0", "--out", "{tmp}"),
    ("ant-trial", "--hand-coded", "--robots", "-3"),
    ("ant-trial", "--hand-coded", "--steps", "99999999999"),
    ("ant-trial", "--hand-coded", "--command-timeout", "nan"),
    ("ant-trial", "--hand-coded", "--domain", "500"),
]


@pytest.mark.parametrize("argv", HOSTILE_OPTIONS, ids=lambda a: " ".join(a[1:]))
def test_hostile_numbers(argv: tuple[str, ...], tmp_path: Path) -> None:
    done = run(*(a.replace("{tmp}", str(tmp_path / "out")) for a in argv))
    assert "Traceback" not in done.stderr, done.stderr
    assert done.returncode == 2, done.stderr
    last = done.stderr.strip().splitlines()[-1]
    option = next(a for a in argv if a.startswith("--") and a != "--hand-coded" and a != "--out")
    assert option in last and ("limit" in last or "must be" in last), last


@pytest.mark.parametrize(
    "argv, fragment",
    [
        (("ant-eval", "--hand-coded", "--scenarios", "100000", "--steps", "100000"), "steps + 1"),
        (("ant-evolve", "--out", "{tmp}", "--population", "10000", "--scenarios", "100000"), "x"),
    ],
)
def test_workload_products(argv: tuple[str, ...], fragment: str, tmp_path: Path) -> None:
    done = run(*(a.replace("{tmp}", str(tmp_path / "out")) for a in argv))
    assert_refused(done, "<command line>", (fragment, "exceeds the limit"))


# --- the loaders ------------------------------------------------------------------------------


class DemoError(FieldError):
    """The caller's error type, which every loader raises."""


@pytest.mark.parametrize(
    "text, field, reason",
    [
        ("a: 1\nb: 2\na: 3\n", "a", "given twice (first at line 1 column 1)"),
        ("a: {x: 1, x: 2}\n", "x", "given twice"),
        ("x: &a [1, 2]\ny: *a\n", "line 2", "aliases are not allowed"),
        ("[" * 40 + "]" * 40, "line 1", "limit of 32 levels"),
        ("a: [1, 2\n", "line 2", "not valid YAML"),
        ("t: 2020-13-45\n", "<yaml>", "cannot be read"),
        ("!!python/object:os.system {}\n", "line 1", "not valid YAML"),
    ],
)
def test_parse_yaml_refuses(text: str, field: str, reason: str) -> None:
    with pytest.raises(DemoError, match="f.yaml") as info:
        parse_yaml(text, "f.yaml", DemoError)
    assert info.value.field == field
    assert reason in info.value.reason


def test_parse_yaml_accepts_plain_documents() -> None:
    assert parse_yaml("a: 1\nb: [x, {c: 2}]\n") == {"a": 1, "b": ["x", {"c": 2}]}
    assert parse_yaml("[" * 31 + "]" * 31) is not None  # 31 lists + nothing: within 32


@pytest.mark.parametrize(
    "text, field, reason",
    [
        ('{"a": 1, "a": 2}', "a", "given twice"),
        ('{"a": {"b": 1, "b": 1}}', "b", "given twice"),
        ("[NaN]", "<json>", "NaN and Infinity"),
        ("[-Infinity]", "<json>", "NaN and Infinity"),
        ("[1e999]", "<json>", "64-bit float"),
        ("[" * 33 + "]" * 33, "<json>", "limit of 32 levels"),
        ("[" * 100000 + "]" * 100000, "<json>", "limit of 32 levels"),
        ('{"a": ', "line 1 column 7", "not valid JSON"),
        ("9" * 5000, "<json>", "cannot be parsed"),
    ],
)
def test_parse_json_refuses(text: str, field: str, reason: str) -> None:
    with pytest.raises(DemoError, match="f.json") as info:
        parse_json(text, "f.json", DemoError)
    assert info.value.field == field
    assert reason in info.value.reason


def test_bounded_read_checks_size_before_reading(tmp_path: Path) -> None:
    big = tmp_path / "big.yaml"
    big.write_text("a: 1\n" * 1000)
    assert read_text_bounded(big, 5000) == "a: 1\n" * 1000
    with pytest.raises(DemoError, match="limit of 4999 bytes"):
        read_text_bounded(big, 4999, DemoError)
    with pytest.raises(DemoError, match="limit of 4999 bytes"):
        load_yaml(big, DemoError, max_bytes=4999)
    with pytest.raises(DemoError, match="does not exist"):
        load_json(tmp_path / "missing.json", DemoError)
    with pytest.raises(DemoError, match="directory"):
        load_yaml(tmp_path, DemoError)
    with pytest.raises(DemoError, match="not a regular file"):
        read_text_bounded("/dev/zero", 100, DemoError)


def test_image_header_sizes(tmp_path: Path) -> None:
    import cv2
    import numpy as np

    picture = np.full((30, 50, 3), 255, np.uint8)
    for suffix in (".png", ".jpg", ".bmp"):
        path = tmp_path / f"p{suffix}"
        assert cv2.imwrite(str(path), picture)
        assert image_size(path) == (50, 30)
    assert check_image(CORPUS / "blueprint/ok_image.png") == (64, 64)
    with pytest.raises(DemoError, match="limit of 16384 pixels a side"):
        check_image(CORPUS / "blueprint/huge_image.png", DemoError)
    with pytest.raises(DemoError, match="more than the limit of 1000 pixels"):
        check_image(tmp_path / "p.png", DemoError, max_pixels=1000)
    (tmp_path / "cut.png").write_bytes((tmp_path / "p.png").read_bytes()[:20])
    with pytest.raises(DemoError, match="truncated header"):
        image_size(tmp_path / "cut.png", DemoError)
    with pytest.raises(DemoError, match="not a PNG, JPEG or BMP"):
        image_size(CORPUS / "blueprint/not_an_image.png", DemoError)
