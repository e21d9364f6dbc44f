"""Every node kind's parameters, declared once: the generated files are current, state exactly
the dataclass defaults, and load through ``--params-file``; bad values are refused.

The registry (``excavation_bringup.kinds``) names each kind's parameter dataclasses and
parameter file; ``excavation_bringup.generate`` writes the files and the tables of
``docs/interfaces.md`` from them (``make params``).
"""

from __future__ import annotations

from dataclasses import fields
from pathlib import Path

import pytest
import yaml
from rclpy.parameter import Parameter

from excavation_bringup import generate
from excavation_bringup.kinds import KINDS
from excavation_common.params import ParameterError, defaults, validate

ROOT = Path(__file__).resolve().parents[1]
WITH_FILE = [name for name, kind in KINDS.items() if kind.config]
# Parameters every rclpy node declares besides its own.
BUILTIN = {"use_sim_time", "start_type_description_service"}


def _defaults(name: str) -> dict:
    """``{parameter: default}`` over every dataclass of kind ``name``."""
    out = {}
    for cls in KINDS[name].param_classes():
        out.update(defaults(cls))
    return out


def _plain(value):
    """A default as YAML and rclpy give it back (tuples are lists)."""
    return list(value) if isinstance(value, tuple) else value


def _same(got, want) -> bool:
    """Equal, and of the same type (1 is not 1.0, and neither is True)."""
    want = _plain(want)
    if isinstance(want, list):
        return (
            isinstance(got, list)
            and len(got) == len(want)
            and all(_same(g, w) for g, w in zip(got, want, strict=True))
        )
    return type(got) is type(want) and got == want


def _shipped(name: str) -> tuple[str, dict]:
    """The node key and the parameters of kind ``name``'s shipped file."""
    kind = KINDS[name]
    doc = yaml.safe_load((ROOT / generate.config_path(kind)).read_text())
    assert isinstance(doc, dict) and len(doc) == 1, f"{kind.config}: one node key expected"
    ((key, section),) = doc.items()
    assert set(section) == {"ros__parameters"}, kind.config
    return key, section["ros__parameters"]


def test_the_generator_finds_its_checkout():
    assert (generate.ROOT / generate.DOCS).is_file()
    assert (generate.ROOT / generate.config_path(KINDS["sim"])).is_file()


def test_generated_files_are_current():
    stale = [p.as_posix() for p in generate.stale(ROOT)]
    assert not stale, f"stale (run make params): {', '.join(stale)}"


def test_check_names_each_stale_file_and_a_run_rewrites_it(tmp_path, capsys):
    for path, text in generate.expected(ROOT).items():
        (tmp_path / path).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / path).write_text(text)
    assert generate.main(["--check", "--root", str(tmp_path)]) == 0
    config = generate.config_path(KINDS["controller"])
    (tmp_path / config).write_text(
        (tmp_path / config).read_text().replace("robots: 1", "robots: 4")
    )
    docs = tmp_path / generate.DOCS
    docs.write_text(docs.read_text().replace("| `robots` | integer | `1` |", "| `robots` |"))
    assert generate.stale(tmp_path) == [config, generate.DOCS]
    assert generate.main(["--check", "--root", str(tmp_path)]) == 1
    out = capsys.readouterr().out
    assert f"stale: {config.as_posix()}" in out and "stale: docs/interfaces.md" in out
    assert generate.main(["--root", str(tmp_path)]) == 0
    assert generate.stale(tmp_path) == []


def test_a_missing_docs_block_is_an_error(tmp_path, capsys):
    docs = tmp_path / generate.DOCS
    docs.parent.mkdir(parents=True)
    text = (ROOT / generate.DOCS).read_text()
    docs.write_text(text.replace("<!-- params:sim -->", "<!-- sim -->"))
    assert generate.main(["--check", "--root", str(tmp_path)]) == 2
    assert "params:sim" in capsys.readouterr().err


@pytest.mark.parametrize(
    "value",
    [1e-06, 0.0008, -0.03, 10.0, 0, 115200, True, False, "", "*/image_raw", "true", "1.0",
     "a: b # c", 'say "hi"', ("",), ("blade",), (0.5, 1.0)],
)  # fmt: skip
def test_values_read_back_as_written(value):
    assert _same(yaml.safe_load(f"x: {generate.fmt_value(value)}")["x"], value)


@pytest.mark.parametrize("name", WITH_FILE)
def test_config_file_states_exactly_the_defaults(name):
    key, values = _shipped(name)
    assert key == generate.NODE_KEY.get(name, "/**")
    want = _defaults(name)
    assert list(values) == list(want), f"{KINDS[name].config}: names or order differ"
    wrong = {n: (values[n], want[n]) for n in want if not _same(values[n], want[n])}
    assert not wrong, f"{KINDS[name].config}: (file, default) {wrong}"
    for cls in KINDS[name].param_classes():  # the defaults pass the node's own checks
        validate(cls, {f.name: values[f.name] for f in fields(cls)}, name)


@pytest.mark.parametrize("name", list(KINDS))
def test_docs_table_lists_every_parameter(name):
    text = (ROOT / generate.DOCS).read_text()
    blocks = {m.group("name"): m.group(0) for m in generate.BLOCK.finditer(text)}
    assert name in blocks, f"docs/interfaces.md has no <!-- params:{name} --> block"
    rows = [line.split(" | ") for line in blocks[name].splitlines() if line.startswith("| `")]
    table = {cells[0].strip("| `"): cells[2].strip("`") for cells in rows}
    want = _defaults(name)
    assert list(table) == list(want)
    assert table == {n: generate.fmt_value(v) for n, v in want.items()}


def _make(name: str, context, args=None, overrides=(), out=None):
    """A node of kind ``name`` (what it needs besides its parameters is given here)."""
    kind = KINDS[name]
    cls = kind.load_class()
    extra = {}
    positional = ()
    overrides = list(overrides)
    if name == "controller":
        from ant_controller.controller import Controller

        positional = (Controller.hand_coded(),)
    if name in ("controller", "blade_driver", "executor"):
        extra["namespace"] = "/robot_0"
    if name == "localizer" and "calibration" not in {p.name for p in overrides}:
        from overhead_localizer.beacons import CONFIG_DIR

        calibration = str(CONFIG_DIR / "camera_sim.yaml")
        overrides.append(Parameter("calibration", value=calibration))
    if name == "recorder":
        overrides.append(Parameter("out", value=str(out)))
    return cls(*positional, context=context, cli_args=args, parameter_overrides=overrides, **extra)


def _stop(node) -> None:
    if type(node).__name__ == "RecorderNode":
        node.close()  # its bag
    node.destroy_node()


def _given(node) -> dict:
    """``{name: value}`` of the node's own parameters."""
    return {n: p.value for n, p in node._parameters.items() if n not in BUILTIN}


# What a node needs besides its parameter file (overrides above); the player needs a bag
# (tests/test_bag_play.py starts it with its file).
STARTED = [n for n in WITH_FILE if n != "player"]
# One harmless change per kind, to see that the node reads the file (not its defaults).
CHANGE = {
    "controller": ("map_timeout", 7.5),
    "executor": ("time_allowance", 20.0),
    "recorder": ("discovery_period", 0.25),
}


@pytest.mark.parametrize("name", STARTED)
def test_node_comes_up_with_its_file(ros, name, tmp_path):
    path = ROOT / generate.config_path(KINDS[name])
    key, values = _shipped(name)
    expect = {n: _plain(v) for n, v in _defaults(name).items()}
    set_here = {"localizer": "calibration", "recorder": "out"}.get(name)
    args = ["--ros-args", "--params-file", str(path)]
    node = _make(name, ros.context, args, out=tmp_path / "bag")
    try:
        got = _given(node)
        assert set(got) == set(values), f"{path.name}: declared {sorted(set(got) ^ set(values))}"
        got.pop(set_here, None)
        wrong = {n: (got[n], expect[n]) for n in got if not _same(got[n], expect[n])}
        assert not wrong, f"{path.name}: (node, default) {wrong}"
    finally:
        _stop(node)
    # the same file with one value changed: the node takes it from the file
    change, value = CHANGE.get(name, ("diagnostics_period", 2.5))
    changed = tmp_path / path.name
    changed.write_text(yaml.safe_dump({key: {"ros__parameters": {**values, change: value}}}))
    args = ["--ros-args", "--params-file", str(changed)]
    node = _make(name, ros.context, args, out=tmp_path / "bag2")
    try:
        assert node.get_parameter(change).value == value != expect[change]
    finally:
        _stop(node)


@pytest.mark.parametrize(
    ("name", "param", "value", "match"),
    [
        ("localizer", "min_value", 300, "min_value = 300: must be <= 255"),
        ("localizer", "robots", 0, "robots = 0: must be >= 1"),
        ("mapper", "tilt_offset", 0.9, "tilt_offset = 0.9: must be <= 0.5"),
        ("mapper", "sweep_scans", 1, "sweep_scans = 1: must be >= 2"),
    ],
)
def test_bad_values_at_start_are_refused(ros, name, param, value, match):
    with pytest.raises(ParameterError, match=match):
        _make(name, ros.context, overrides=[Parameter(param, value=value)])


def test_runtime_changes_are_rejected_with_a_reason(ros):
    node = _make("mapper", ros.context)
    try:
        result = node.set_parameters([Parameter("tilt_offset", value=0.1)])[0]
        assert not result.successful and "read-only" in result.reason
    finally:
        node.destroy_node()
