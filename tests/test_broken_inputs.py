"""Broken and hostile inputs give one clear line and exit code 2, never a traceback.

Every file of the corpus in ``tests/data/broken/`` (rebuilt by its ``make_corpus.py``) is
handed to each command line that reads that kind of file, in a process with its address
space capped at 2 GiB and a timeout: a limit that is checked only after allocating, or an
image decoded before its header is checked, ends in a MemoryError or the timeout instead.
The message must name the file, the field and the limit (``EXPECT``). Then the loaders
themselves (``excavation_common.loaders``) and the hostile command-line numbers.

The files and numbers go through each command's ``main`` (its console script's entry point)
in ONE capped process per command (``tests/cli_batch.py``: each call's exit code and output
of its own), and each command's installed console script runs once end to end
(:func:`test_console_script_does_what_its_main_does`).
"""

from __future__ import annotations

import json
import subprocess
import sys
from importlib.metadata import entry_points
from pathlib import Path

import pytest
from helpers.limits import limited

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
BATCH = ROOT / "tests" / "cli_batch.py"
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


# Every command line that reads a kind of corpus file: (kind, files, its command line for a
# file). ``{dir}`` is an empty folder of the run's own, ``{tmp}`` a path in it (not there).
READERS = {
    "blueprint_info": ("blueprint", "*.yaml", lambda f: ("blueprint_info", f)),
    "ant_eval_blueprint": (
        "blueprint",
        "*.yaml",
        lambda f: ("ant-eval", "--hand-coded", "--blueprint", f, "--scenarios", "1"),
    ),
    "genome_info": ("genome", "*.json", lambda f: ("genome_info", f)),
    "ant_eval_genome": (
        "genome",
        "*.json",
        lambda f: ("ant-eval", "--genome", f, "--scenarios", "1"),
    ),
    "ant_evolve_config": (
        "config",
        "*.yaml",
        lambda f: ("ant-evolve", "--config", f, "--out", "{dir}", "--quiet"),
    ),
    "calibrate_marks": (
        "localizer",
        "marks_*.yaml",
        lambda f: ("calibrate", f, "--out", "{dir}/c.yaml"),
    ),
    "field_metrics": ("map", "*.npy", lambda f: ("field-metrics", f, f)),
}


def reads(reader: str, rel: str) -> tuple[str, ...]:
    """The command line with which ``reader`` reads corpus file ``rel``."""
    return READERS[reader][2](f"tests/data/broken/{rel}")


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

WORKLOAD_PRODUCTS = [
    (("ant-eval", "--hand-coded", "--scenarios", "100000", "--steps", "100000"), "steps + 1"),
    (("ant-evolve", "--out", "{tmp}", "--population", "10000", "--scenarios", "100000"), "x"),
]

# Every command line run through a main: the corpus's, the hostile numbers', the workloads'.
ALL_CALLS = (
    [
        reads(reader, rel)
        for reader, (kind, pattern, _) in READERS.items()
        for rel in corpus(kind, pattern)
    ]
    + HOSTILE_OPTIONS
    + [argv for argv, _ in WORKLOAD_PRODUCTS]
)

# One run per command of its installed console script, end to end (an input of each).
CONSOLE_RUNS = [
    reads("blueprint_info", "blueprint/huge_image.yaml"),
    reads("ant_eval_blueprint", "blueprint/alias_bomb.yaml"),
    reads("genome_info", "genome/huge_integer.json"),
    reads("ant_evolve_config", "config/huge_workload.yaml"),
    reads("calibrate_marks", "localizer/marks_deep_nesting.yaml"),
    reads("field_metrics", "map/huge_shape.npy"),
    *(
        next(a for a in HOSTILE_OPTIONS if a[0] == c)
        for c in ("ant-sweep", "ant-experiment", "ant-trial")
    ),
]


def on(command: str) -> pytest.MarkDecorator:
    """One xdist group per command: its main's process runs once (``--dist loadgroup``)."""
    return pytest.mark.xdist_group(f"cli-{command}")


def entry_point(command: str) -> str:
    """``module:function`` of an installed console script (what its script imports)."""
    (found,) = entry_points(group="console_scripts").select(name=command)
    return found.value


def substitute(argv: tuple[str, ...], workdir: Path) -> list[str]:
    """``argv`` with ``{dir}`` the folder ``workdir`` (made) and ``{tmp}`` ``{dir}/out``."""
    workdir.mkdir(parents=True, exist_ok=True)
    return [a.replace("{tmp}", str(workdir / "out")).replace("{dir}", str(workdir)) for a in argv]


def run(argv: tuple[str, ...], workdir: Path) -> subprocess.CompletedProcess:
    """A console script of the venv, memory-capped, with a timeout."""
    return subprocess.run(
        limited([str(BIN / argv[0]), *substitute(argv[1:], workdir)], AS=MEMORY_LIMIT),
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=TIMEOUT,
        check=False,
    )


def _text(output: str | bytes | None) -> str:
    return output.decode(errors="replace") if isinstance(output, bytes) else output or ""


def run_mains(command: str, calls: list[tuple[str, ...]], workdir: Path) -> dict:
    """Every argument list of ``calls`` through ``command``'s ``main``, in ONE process.

    The process (``tests/cli_batch.py``) is memory-capped as :func:`run`'s are, and each
    call has :data:`TIMEOUT` seconds. Returns a ``CompletedProcess`` per argument list (as
    given: ``{dir}`` and ``{tmp}`` unsubstituted); a call that ran out of time, or that the
    process did not report (it died), has return code None and says why on its stderr.
    """
    request = {
        "entry": entry_point(command),
        "prog": command,
        "calls": [substitute(argv, workdir / str(i)) for i, argv in enumerate(calls)],
        "timeout": TIMEOUT,
    }
    backstop = 2 * TIMEOUT + 10 * len(calls)
    try:
        done = subprocess.run(
            limited([sys.executable, str(BATCH)], AS=MEMORY_LIMIT),
            cwd=ROOT,
            input=json.dumps(request),
            capture_output=True,
            text=True,
            timeout=backstop,
            check=False,
        )
        out, err, how = done.stdout, done.stderr, f"exited with {done.returncode}"
    except subprocess.TimeoutExpired as e:
        out, err, how = _text(e.stdout), _text(e.stderr), f"was stopped after {backstop} s"
    results = {}
    for line in out.splitlines():
        r = json.loads(line)
        late = f"\n(still running after {TIMEOUT} s)" if r["returncode"] is None else ""
        argv = calls[r["index"]]
        results[argv] = subprocess.CompletedProcess(
            argv, r["returncode"], r["stdout"], r["stderr"] + late
        )
    lost = f"no result: {BATCH.name} {how} before this call ended:\n{err[-3000:]}"
    return {
        argv: results.get(argv, subprocess.CompletedProcess(argv, None, "", lost)) for argv in calls
    }


@pytest.fixture(scope="module")
def mains(tmp_path_factory):
    """``mains(argv)``: what ``argv`` gave through its command's ``main``.

    Each command's calls (every one of :data:`ALL_CALLS`) run in one process
    (:func:`run_mains`) when one of them is first asked for.
    """
    done: dict[str, dict] = {}

    def result(argv: tuple[str, ...]) -> subprocess.CompletedProcess:
        command = argv[0]
        if command not in done:
            calls = list(dict.fromkeys(a[1:] for a in ALL_CALLS if a[0] == command))
            done[command] = run_mains(command, calls, tmp_path_factory.mktemp(command))
        return done[command][argv[1:]]

    return result


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


def test_every_command_runs_its_console_script_once() -> None:
    assert sorted(a[0] for a in CONSOLE_RUNS) == sorted({a[0] for a in ALL_CALLS})
    assert all(argv in ALL_CALLS for argv in CONSOLE_RUNS)


def test_soil_sums_fit_the_kernels_integer_type() -> None:
    # Every goal at the deepest depth on the largest grid, and a difference of two such sums.
    assert 2 * MAX_GRID_CELLS * MAX_DEPTH_UNITS < INT32_MAX


@pytest.mark.parametrize("argv", [pytest.param(a, marks=on(a[0]), id=a[0]) for a in CONSOLE_RUNS])
def test_console_script_does_what_its_main_does(argv, mains, tmp_path: Path) -> None:
    """The installed script, end to end, refuses as its main did in the batch."""
    done = run(argv, tmp_path)
    assert "Traceback" not in done.stderr and "MemoryError" not in done.stderr, done.stderr
    assert done.returncode == 2, (done.returncode, done.stderr)
    through_main = mains(argv)
    assert (done.returncode, done.stderr) == (through_main.returncode, through_main.stderr)


# --- every file through every command line that reads its kind ------------------------------


@on("blueprint_info")
@pytest.mark.parametrize("rel", corpus("blueprint", "*.yaml"))
def test_blueprint_info(rel: str, mains) -> None:
    assert_refused(mains(reads("blueprint_info", rel)), rel, EXPECT[rel])


@on("ant-eval")
@pytest.mark.parametrize("rel", corpus("blueprint", "*.yaml"))
def test_ant_eval_blueprint(rel: str, mains) -> None:
    assert_refused(mains(reads("ant_eval_blueprint", rel)), rel, EXPECT[rel])


@on("genome_info")
@pytest.mark.parametrize("rel", corpus("genome", "*.json"))
def test_genome_info(rel: str, mains) -> None:
    assert_refused(mains(reads("genome_info", rel)), rel, EXPECT[rel])


@on("ant-eval")
@pytest.mark.parametrize("rel", corpus("genome", "*.json"))
def test_ant_eval_genome(rel: str, mains) -> None:
    assert_refused(mains(reads("ant_eval_genome", rel)), rel, EXPECT[rel])


@on("ant-evolve")
@pytest.mark.parametrize("rel", corpus("config", "*.yaml"))
def test_ant_evolve_config(rel: str, mains) -> None:
    name = "huge_grid.yaml" if rel == "config/broken_blueprint.yaml" else rel
    assert_refused(mains(reads("ant_evolve_config", rel)), name, EXPECT[rel])


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


@on("calibrate")
@pytest.mark.parametrize("rel", corpus("localizer", "marks_*.yaml"))
def test_calibrate_marks(rel: str, mains) -> None:
    assert_refused(mains(reads("calibrate_marks", rel)), rel, EXPECT[rel])


@on("field-metrics")
@pytest.mark.parametrize("rel", corpus("map", "*.npy"))
def test_field_metrics(rel: str, mains) -> None:
    assert_refused(mains(reads("field_metrics", rel)), rel, EXPECT[rel])


# --- command-line numbers ---------------------------------------------------------------------


@pytest.mark.parametrize(
    "argv", [pytest.param(a, marks=on(a[0]), id=" ".join(a)) for a in HOSTILE_OPTIONS]
)
def test_hostile_numbers(argv: tuple[str, ...], mains) -> None:
    done = mains(argv)
    assert "Traceback" not in done.stderr, done.stderr
    assert done.returncode == 2, done.stderr
    last = done.stderr.strip().splitlines()[-1]
    option = next(a for a in argv if a.startswith("--") and a != "--hand-coded" and a != "--out")
    assert option in last and ("limit" in last or "must be" in last), last


@pytest.mark.parametrize(
    "argv, fragment",
    [pytest.param(a, f, marks=on(a[0]), id=a[0]) for a, f in WORKLOAD_PRODUCTS],
)
def test_workload_products(argv: tuple[str, ...], fragment: str, mains) -> None:
    assert_refused(mains(argv), "<command line>", (fragment, "exceeds the limit"))


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
    nested: list = []  # 31 lists, one inside the other: within 32
    for _ in range(30):
        nested = [nested]
    assert parse_yaml("[" * 31 + "]" * 31) == nested


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
