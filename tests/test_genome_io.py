"""Tests for genome files: round trip, atomic save, validation errors and the info CLI."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from ant_controller import genome_info
from ant_controller.errors import GenomeFormatError
from ant_controller.genome import Lattice, random_genome
from ant_controller.genome_io import (
    FORMAT,
    genome_from_dict,
    genome_to_dict,
    load_genome,
    save_genome,
)

METADATA = {
    "fitness": 0.91,
    "generation": 120,
    "seed": 3,
    "config": {"robots": 4, "scenarios": [1, 2, 3], "name": "demo", "flag": True, "x": None},
}


def _genome(seed: int = 0, **kwargs):
    return random_genome(np.random.default_rng(seed), **kwargs)


def _good_dict(seed: int = 0) -> dict:
    # A fresh, JSON-clean copy of a valid genome mapping.
    return json.loads(json.dumps(genome_to_dict(_genome(seed))))


# --- round trip -------------------------------------------------------------------------------


@pytest.mark.parametrize("seed", [0, 1, 2, 7, 42, 1234])
def test_save_load_round_trip(tmp_path, seed):
    g = dataclasses.replace(_genome(seed), metadata={**METADATA, "seed": seed})
    path = tmp_path / f"g{seed}.json"
    save_genome(g, path)
    loaded = load_genome(path)
    assert loaded == g
    assert loaded.cells == g.cells
    assert loaded.tissue == g.tissue
    assert loaded.lattice == g.lattice
    assert loaded.coarse_coding == g.coarse_coding
    # metadata is excluded from Genome equality: check it on its own
    assert loaded.metadata == {**METADATA, "seed": seed}
    assert genome_to_dict(loaded) == genome_to_dict(g)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"coarse_coding": False},
        {"robots": 7},
        {"lattice": Lattice(half_width=5, layers=2)},
        {"lattice": Lattice(half_width=8, layers=1), "n_neurons": (40, 60)},
    ],
    ids=["no-coarse-coding", "robots", "small-lattice", "one-layer"],
)
def test_round_trip_non_default_fields(tmp_path, kwargs):
    g = _genome(5, **kwargs)
    path = tmp_path / "g.json"
    save_genome(g, path)
    loaded = load_genome(path)
    assert loaded == g
    assert loaded.metadata == {}


def test_round_trip_with_repressed_and_dead_cells(tmp_path):
    g = _genome(11)
    cells = list(g.cells)
    cells[0] = dataclasses.replace(cells[0], expressed=False)
    cells[1] = dataclasses.replace(cells[1], dead=True)
    g = dataclasses.replace(g, cells=tuple(cells))
    path = tmp_path / "g.json"
    save_genome(g, path)
    loaded = load_genome(path)
    assert loaded == g
    assert loaded.cells[0].expressed is False
    assert loaded.cells[1].dead is True


def test_saved_file_is_the_documented_json(tmp_path):
    g = _genome(3)
    path = tmp_path / "g.json"
    save_genome(g, path)
    data = json.loads(path.read_text(encoding="utf-8"))
    assert data["format"] == FORMAT == "ant-genome/1"
    assert len(data["cells"]) == g.n_cells
    assert data == json.loads(json.dumps(genome_to_dict(g)))


def test_optional_controller_and_metadata_default(tmp_path):
    d = _good_dict(4)
    del d["controller"]
    del d["metadata"]
    g = genome_from_dict(d)
    assert g.coarse_coding is True
    assert g.metadata == {}
    d["controller"] = {"coarse_coding": False}
    assert genome_from_dict(d).coarse_coding is False


# --- atomic save ------------------------------------------------------------------------------


def test_save_leaves_no_temporary_files(tmp_path):
    path = tmp_path / "best.json"
    for seed in range(3):  # also overwrites an existing file
        save_genome(_genome(seed), path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["best.json"]
    assert load_genome(path) == _genome(2)


def test_save_creates_parent_directories(tmp_path):
    path = tmp_path / "a" / "b" / "g.json"
    save_genome(_genome(0), path)
    assert [p.name for p in path.parent.iterdir()] == ["g.json"]
    assert load_genome(path) == _genome(0)


def test_failed_save_keeps_old_file_and_leaves_no_temporary(tmp_path):
    path = tmp_path / "best.json"
    good = _genome(0)
    save_genome(good, path)
    before = path.read_bytes()
    g = _genome(1)
    bad = dataclasses.replace(g, cells=(dataclasses.replace(g.cells[0], theta1=float("nan")),))
    with pytest.raises(ValueError):
        save_genome(bad, path)
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["best.json"]


# --- malformed files --------------------------------------------------------------------------


def _set(*keys_and_value):
    *keys, value = keys_and_value

    def mutate(d):
        obj = d
        for k in keys[:-1]:
            obj = obj[k]
        obj[keys[-1]] = value
        return d

    return mutate


def _delete(*keys):
    def mutate(d):
        obj = d
        for k in keys[:-1]:
            obj = obj[k]
        del obj[keys[-1]]
        return d

    return mutate


def _write(mutate):
    def write(path: Path) -> None:
        d = mutate(_good_dict(0))
        path.write_text(json.dumps(d, indent=1, allow_nan=True), encoding="utf-8")

    return write


def _missing(path: Path) -> None:
    pass  # write nothing


def _truncated(path: Path) -> None:
    text = json.dumps(_good_dict(0), indent=1)
    path.write_text(text[: len(text) // 2], encoding="utf-8")


def _truncated_field(path: Path) -> str:
    with pytest.raises(json.JSONDecodeError) as info:
        json.loads(path.read_text(encoding="utf-8"))
    return f"line {info.value.lineno} column {info.value.colno}"


def _literal(text):
    def write(path: Path) -> None:
        path.write_text(text, encoding="utf-8")

    return write


def _nan_weight(d):
    d["cells"][0]["sensor_weights"][2] = float("nan")
    return d


def _infinite_theta(d):
    d["cells"][1]["theta1"] = float("inf")
    return d


def _duplicate_site(d):
    d["cells"][3]["position"] = list(d["cells"][1]["position"])
    return d


def _wrong_sensor_layout(d):
    d["layout"]["sensors"][0]["states"] = 6
    return d


def _wrong_behaviours(d):
    d["layout"]["behaviours"] = list(reversed(d["layout"]["behaviours"]))
    return d


def _short_sensor_weights(d):
    d["cells"][0]["sensor_weights"] = d["cells"][0]["sensor_weights"][:13]
    return d


def _string_weight(d):
    d["cells"][0]["sensor_weights"][3] = "0.5"
    return d


BAD_FILES = [
    pytest.param(_missing, "<file>", id="missing-file"),
    pytest.param(_truncated, _truncated_field, id="truncated-json"),
    pytest.param(_literal("[1, 2, 3]"), "<root>", id="not-an-object"),
    pytest.param(_literal(""), "line 1 column 1", id="empty-file"),
    pytest.param(_write(_set("format", "ant-genome/0")), "format", id="wrong-format-tag"),
    pytest.param(_write(_delete("format")), "format", id="missing-format-tag"),
    pytest.param(_write(_delete("cells")), "cells", id="missing-cells"),
    pytest.param(_write(_set("cells", {})), "cells", id="cells-not-a-list"),
    pytest.param(_write(_set("extra", 1)), "extra", id="unknown-top-level-key"),
    pytest.param(_write(_delete("cells", 0, "theta1")), "cells[0].theta1", id="missing-cell-field"),
    pytest.param(
        _write(_set("cells", 0, "colour", "red")), "cells[0].colour", id="unknown-cell-key"
    ),
    pytest.param(_write(_set("cells", 0, "kind", "sensor")), "cells[0].kind", id="bad-kind"),
    pytest.param(_write(_set("cells", 2, 7)), "cells[2]", id="cell-not-an-object"),
    pytest.param(_write(_nan_weight), "<json>", id="nan-weight"),
    pytest.param(_write(_infinite_theta), "<json>", id="infinite-theta"),
    pytest.param(_write(_string_weight), "cells[0].sensor_weights[3]", id="string-weight"),
    pytest.param(
        _write(_set("cells", 0, "input_weights", [True] * 9)),
        "cells[0].input_weights[0]",
        id="bool-weight",
    ),
    pytest.param(
        _write(_set("cells", 2, "position", [9, 0, 0])), "cells[2].position", id="outside-l"
    ),
    pytest.param(
        _write(_set("cells", 2, "position", [0, 0, 3])), "cells[2].position", id="outside-layer"
    ),
    pytest.param(
        _write(_set("cells", 2, "position", [0, 0])), "cells[2].position", id="position-2d"
    ),
    pytest.param(_write(_duplicate_site), "cells[3].position", id="two-cells-same-site"),
    pytest.param(_write(_wrong_sensor_layout), "layout.sensors", id="wrong-sensor-layout"),
    pytest.param(_write(_wrong_behaviours), "layout.behaviours", id="wrong-behaviours"),
    pytest.param(
        _write(_set("layout", "encoding", "one-hot")), "layout.encoding", id="wrong-encoding"
    ),
    pytest.param(
        _write(_short_sensor_weights), "cells[0].sensor_weights", id="sensor-weights-length"
    ),
    pytest.param(_write(_set("cells", 0, "k1", 2)), "cells[0].k1", id="k1-is-2"),
    pytest.param(
        _write(_set("cells", 0, "behaviour", 12)), "cells[0].behaviour", id="behaviour-12"
    ),
    pytest.param(
        _write(_set("cells", 0, "concentration", -0.25)),
        "cells[0].concentration",
        id="negative-concentration",
    ),
    pytest.param(
        _write(_set("cells", 0, "replication", 1.5)), "cells[0].replication", id="replication>1"
    ),
    pytest.param(
        _write(_set("cells", 0, "extent", [1, 5, 1])), "cells[0].extent[1]", id="extent-too-large"
    ),
    pytest.param(
        _write(_set("tissue", "seed", [0, 0, 0])), "tissue.seed", id="seed-outside-lattice"
    ),
    pytest.param(_write(_set("lattice", "layers", 5)), "lattice.layers", id="five-layers"),
    pytest.param(
        _write(_set("lattice", "half_width", 0)), "lattice.half_width", id="half-width-zero"
    ),
    pytest.param(
        _write(_set("cells", 0, "expressed", 1)), "cells[0].expressed", id="expressed-is-1"
    ),
    pytest.param(_write(_set("cells", 1, "dead", "no")), "cells[1].dead", id="dead-is-string"),
    pytest.param(_write(_set("tissue", "robots", 0)), "tissue.robots", id="zero-robots"),
    pytest.param(
        _write(_set("tissue", "decision_ratio", -0.1)),
        "tissue.decision_ratio",
        id="negative-decision-ratio",
    ),
    pytest.param(
        _write(_set("controller", "coarse_coding", "yes")),
        "controller.coarse_coding",
        id="coarse-coding-string",
    ),
    pytest.param(_write(_set("metadata", [1])), "metadata", id="metadata-not-an-object"),
    # Integers too large for a float: the loader promises GenomeFormatError for any problem.
    pytest.param(
        _write(_set("cells", 0, "theta1", 10**400)), "cells[0].theta1", id="huge-int-theta1"
    ),
    pytest.param(
        _write(_set("cells", 1, "sensor_weights", [10**400] * 14)),
        "cells[1].sensor_weights[0]",
        id="huge-int-weight",
    ),
]


@pytest.mark.parametrize(("write", "field"), BAD_FILES)
def test_bad_file_is_rejected_with_field(tmp_path, write, field):
    path = tmp_path / "bad.json"
    write(path)
    if callable(field):
        field = field(path)
    with pytest.raises(GenomeFormatError) as info:
        load_genome(path)
    exc = info.value
    assert exc.field == field
    assert exc.path == str(path)
    assert str(path) in str(exc)
    assert f": {field} = " in str(exc)
    assert exc.reason and str(exc).endswith(exc.reason)
    assert isinstance(exc, ValueError)


def _huge_literal(path: Path) -> None:
    d = _good_dict(0)
    d["cells"][0]["theta1"] = "HUGE"
    text = json.dumps(d).replace('"HUGE"', "1" + "0" * 5000)
    path.write_text(text, encoding="utf-8")


@pytest.mark.parametrize(
    "write",
    [
        _huge_literal,  # json raises ValueError (int max str digits)
        _literal("[" * 100_000 + "]" * 100_000),  # json raises RecursionError
    ],
    ids=["5000-digit-integer", "deeply-nested"],
)
def test_pathological_json_is_a_format_error(tmp_path, write):
    path = tmp_path / "bad.json"
    write(path)
    with pytest.raises(GenomeFormatError) as info:
        load_genome(path)
    assert str(path) in str(info.value)


def test_bad_values_are_reported():
    d = _good_dict(0)
    d["cells"][0]["k1"] = 2
    with pytest.raises(GenomeFormatError) as info:
        genome_from_dict(d, "x.json")
    assert (info.value.path, info.value.field, info.value.value) == ("x.json", "cells[0].k1", 2)

    d = _good_dict(0)
    del d["cells"][0]["theta1"]
    with pytest.raises(GenomeFormatError) as info:
        genome_from_dict(d)
    assert info.value.value is None
    assert info.value.path == "<memory>"


def test_nan_in_mapping_is_rejected_without_json():
    d = _good_dict(0)
    d["cells"][4]["input_weights"][8] = float("nan")
    with pytest.raises(GenomeFormatError) as info:
        genome_from_dict(d, "mem")
    assert info.value.field == "cells[4].input_weights[8]"
    d = _good_dict(0)
    d["cells"][4]["theta2"] = float("-inf")
    with pytest.raises(GenomeFormatError) as info:
        genome_from_dict(d, "mem")
    assert info.value.field == "cells[4].theta2"


def test_error_message_format():
    exc = GenomeFormatError("g.json", "cells[0].k1", 2, "must lie in 0..1")
    assert str(exc) == "g.json: cells[0].k1 = 2: must lie in 0..1"
    assert (exc.path, exc.field, exc.value, exc.reason) == (
        "g.json",
        "cells[0].k1",
        2,
        "must lie in 0..1",
    )
    long = GenomeFormatError(Path("p"), "f", "x" * 200, "r")
    assert long.path == "p"
    shown = str(long)[len("p: f = ") : -len(": r")]
    assert len(shown) == 80 and shown.endswith("...")


# --- genome_info CLI ----------------------------------------------------------------------------


def test_genome_info_good_file(tmp_path, capsys):
    path = tmp_path / "g.json"
    save_genome(dataclasses.replace(_genome(0), metadata={"fitness": 0.5}), path)
    assert genome_info.main([str(path)]) == 0
    out, err = capsys.readouterr()
    assert err == ""
    assert "genes" in out and "0.5" in out


def test_genome_info_json_output(tmp_path, capsys):
    g = _genome(1)
    path = tmp_path / "g.json"
    save_genome(g, path)
    assert genome_info.main([str(path), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["genes"] == g.n_cells
    assert info["file"] == str(path)
    assert info["coarse_coding"] is True


@pytest.mark.parametrize(
    ("write", "field"),
    [
        (_missing, "<file>"),
        (_write(_set("cells", 0, "k1", 2)), "cells[0].k1"),
        (_write(_nan_weight), "<json>"),
        (_write(_set("cells", 0, "theta1", 10**400)), "cells[0].theta1"),
    ],
    ids=["missing", "k1", "nan", "huge-int"],
)
def test_genome_info_bad_file(tmp_path, capsys, write, field):
    path = tmp_path / "bad.json"
    write(path)
    assert genome_info.main([str(path)]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    assert str(path) in err
    assert field in err
    assert err.startswith("genome_info: error: ")


# --- limits ------------------------------------------------------------------------------------


def test_gene_count_limit(tmp_path: Path) -> None:
    from ant_controller.limits import MAX_GENES

    data = _good_dict()
    data["cells"] = [data["cells"][0]] * (MAX_GENES + 1)
    with pytest.raises(GenomeFormatError, match=f"limit of {MAX_GENES} genes") as info:
        genome_from_dict(data, "g.json")
    assert info.value.field == "cells"


def test_genome_file_size_limit(tmp_path: Path) -> None:
    from ant_controller.limits import MAX_GENOME_BYTES

    path = tmp_path / "big.json"
    with path.open("wb") as f:
        f.truncate(MAX_GENOME_BYTES + 1)  # sparse: costs no disk
    with pytest.raises(GenomeFormatError, match=f"limit of {MAX_GENOME_BYTES} bytes"):
        load_genome(path)


def test_duplicate_key_and_team_limit(tmp_path: Path) -> None:
    from ant_controller.limits import MAX_ROBOTS

    path = tmp_path / "g.json"
    text = json.dumps(_good_dict())
    path.write_text(text.replace('"format": ', '"format": "x", "format": ', 1))
    with pytest.raises(GenomeFormatError, match="given twice") as info:
        load_genome(path)
    assert info.value.field == "format"
    data = _good_dict()
    data["tissue"]["robots"] = MAX_ROBOTS + 1
    with pytest.raises(GenomeFormatError, match=f"1..{MAX_ROBOTS}"):
        genome_from_dict(data, "g.json")
    data["tissue"]["robots"] = MAX_ROBOTS
    assert genome_from_dict(data, "g.json").tissue.robots == MAX_ROBOTS
