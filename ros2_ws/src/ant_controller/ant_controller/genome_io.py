"""Genome files: ``ant-genome/1`` JSON, saved atomically and loaded with full validation.

Layout of a file (``docs/genome-format.md`` has a complete example)::

    {
      "format": "ant-genome/1",
      "layout": {"sensors": [{"name": "Z1", "states": 5}, ...],
                 "behaviours": ["throttle_up", ...], "encoding": "scalar"},
      "lattice": {"half_width": 8, "layers": 3},
      "controller": {"coarse_coding": true},
      "tissue": {"replication_probability": 0.05, "decision_ratio": 0.2,
                 "seed": [0, 0, 1], "robots": null},
      "cells": [{"kind": "motor", "expressed": true, "dead": false,
                 "position": [0, 1, 0], "replication": 0.4, "theta1": 0.1,
                 "theta2": -0.3, "k1": 0, "k2": 1, "sensor_weights": [... 14],
                 "input_weights": [... 9], "behaviour": 1, "concentration": 0.7,
                 "extent": [1, 2, 1]}, ...],
      "metadata": {"fitness": 0.91, "generation": 120, "seed": 3, "config": {...}}
    }

Loading never executes or unpickles anything: it parses JSON and checks every field,
raising :class:`GenomeFormatError` with the file, the field path and the value. The limits
of :mod:`ant_controller.limits` (file size, nesting, gene count, lattice, team size) are
checked before anything is built from the file; a key given twice is an error.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from ant_controller.errors import GenomeFormatError
from ant_controller.genome import (
    KINDS,
    MAX_EXTENT,
    N_NOMINAL_INPUTS,
    CellGene,
    Genome,
    Lattice,
    TissueGene,
)
from ant_controller.layout import N_BEHAVIOURS, N_SENSORS, layout_dict
from ant_controller.limits import (
    MAX_GENES,
    MAX_GENOME_BYTES,
    MAX_HALF_WIDTH,
    MAX_LAYERS,
    MAX_NESTING,
    MAX_ROBOTS,
)
from excavation_common.files import write_text_atomic
from excavation_common.loaders import load_json

FORMAT = "ant-genome/1"

_TOP_KEYS = {"format", "layout", "lattice", "controller", "tissue", "cells", "metadata"}
_CELL_KEYS = {
    "kind",
    "expressed",
    "dead",
    "position",
    "replication",
    "theta1",
    "theta2",
    "k1",
    "k2",
    "sensor_weights",
    "input_weights",
    "behaviour",
    "concentration",
    "extent",
}
_TISSUE_KEYS = {"replication_probability", "decision_ratio", "seed", "robots"}


def genome_to_dict(genome: Genome) -> dict:
    """The JSON-ready mapping of a genome.

    Every cell carries every parameter, also those its kind does not use (a motor
    neuron's concentration, a decision neuron's behaviour): gene duplication may copy them
    into a cell of the other kind, and the file round-trips exactly.
    """
    cells = []
    for g in genome.cells:
        d = {
            "kind": g.kind,
            "expressed": g.expressed,
            "dead": g.dead,
            "position": list(g.position),
            "replication": g.replication,
            "theta1": g.theta1,
            "theta2": g.theta2,
            "k1": g.k1,
            "k2": g.k2,
            "sensor_weights": list(g.sensor_weights),
            "input_weights": list(g.input_weights),
            "behaviour": g.behaviour,
            "concentration": g.concentration,
            "extent": list(g.extent),
        }
        cells.append(d)
    t = genome.tissue
    return {
        "format": FORMAT,
        "layout": layout_dict(),
        "lattice": {"half_width": genome.lattice.half_width, "layers": genome.lattice.layers},
        "controller": {"coarse_coding": genome.coarse_coding},
        "tissue": {
            "replication_probability": t.replication_probability,
            "decision_ratio": t.decision_ratio,
            "seed": list(t.seed),
            "robots": t.robots,
        },
        "cells": cells,
        "metadata": genome.metadata,
    }


def save_genome(genome: Genome, path: str | Path) -> None:
    """Write a genome file atomically (temporary file, fsync, rename)."""
    write_text_atomic(path, json.dumps(genome_to_dict(genome), indent=1, allow_nan=False) + "\n")


def load_genome(path: str | Path) -> Genome:
    """Read and validate a genome file.

    Raises:
        GenomeFormatError: For any problem, naming the file, the field and the value.
    """
    label = str(path)
    data = load_json(label, GenomeFormatError, max_bytes=MAX_GENOME_BYTES, max_depth=MAX_NESTING)
    return genome_from_dict(data, label)


# --- validation ------------------------------------------------------------------------------


def _is_finite(v: int | float) -> bool:
    """True for a number that is finite as a float (huge JSON integers are not)."""
    try:
        return math.isfinite(v)
    except OverflowError:
        return False


class _Checker:
    """Field readers that raise :class:`GenomeFormatError` with the full field path."""

    def __init__(self, path: str) -> None:
        self.path = path

    def fail(self, field: str, value: object, reason: str) -> GenomeFormatError:
        return GenomeFormatError(self.path, field, value, reason)

    def mapping(self, obj: object, field: str, allowed: set[str], required: set[str]) -> dict:
        if not isinstance(obj, dict):
            raise self.fail(field, obj, "must be a JSON object")
        for key in sorted(required):
            if key not in obj:
                raise self.fail(f"{field}.{key}" if field else key, None, "is missing")
        for key in sorted(obj):
            if key not in allowed:
                raise self.fail(
                    f"{field}.{key}" if field else key, obj[key], "is not a known field"
                )
        return obj

    def number(
        self, obj: dict, key: str, field: str, lo: float = -math.inf, hi: float = math.inf
    ) -> float:
        v = obj[key]
        if isinstance(v, bool) or not isinstance(v, int | float):
            raise self.fail(field, v, "must be a number")
        if not _is_finite(v):
            raise self.fail(field, v, "must be finite")
        if not lo <= v <= hi:
            raise self.fail(field, v, f"must lie in [{lo}, {hi}]")
        return float(v)

    def integer(self, v: object, field: str, lo: int, hi: int) -> int:
        if isinstance(v, bool) or not isinstance(v, int):
            raise self.fail(field, v, "must be an integer")
        if not lo <= v <= hi:
            raise self.fail(field, v, f"must lie in {lo}..{hi}")
        return int(v)

    def boolean(self, obj: dict, key: str, field: str) -> bool:
        v = obj[key]
        if not isinstance(v, bool):
            raise self.fail(field, v, "must be true or false")
        return v

    def vector(self, obj: dict, key: str, field: str, length: int) -> tuple[float, ...]:
        v = obj[key]
        if not isinstance(v, list) or len(v) != length:
            raise self.fail(field, v, f"must be a list of {length} numbers")
        out = []
        for i, w in enumerate(v):
            if isinstance(w, bool) or not isinstance(w, int | float) or not _is_finite(w):
                raise self.fail(f"{field}[{i}]", w, "must be a finite number")
            out.append(float(w))
        return tuple(out)

    def int_triple(self, obj: dict, key: str, field: str, lo: int, hi: int) -> tuple[int, int, int]:
        v = obj[key]
        if not isinstance(v, list) or len(v) != 3:
            raise self.fail(field, v, "must be a list of 3 integers")
        return tuple(self.integer(x, f"{field}[{i}]", lo, hi) for i, x in enumerate(v))


def genome_from_dict(data: object, path: str = "<memory>") -> Genome:
    """Validate a parsed genome mapping and build the :class:`Genome`.

    Raises:
        GenomeFormatError: Naming ``path``, the field and the value at fault.
    """
    ck = _Checker(path)
    if not isinstance(data, dict):
        raise ck.fail("<root>", type(data).__name__, "must be a JSON object")
    if data.get("format") != FORMAT:
        raise ck.fail("format", data.get("format"), f"must be '{FORMAT}'")
    ck.mapping(data, "", _TOP_KEYS, _TOP_KEYS - {"metadata", "controller"})

    expected = layout_dict()
    layout = ck.mapping(data["layout"], "layout", set(expected), set(expected))
    for key in ("sensors", "behaviours", "encoding"):
        if layout[key] != expected[key]:
            raise ck.fail(
                f"layout.{key}",
                layout[key],
                f"this controller uses {expected[key]!r}; the genome was trained for another "
                "layout",
            )

    lat = ck.mapping(data["lattice"], "lattice", {"half_width", "layers"}, {"half_width", "layers"})
    lattice = Lattice(
        ck.integer(lat["half_width"], "lattice.half_width", 1, MAX_HALF_WIDTH),
        ck.integer(lat["layers"], "lattice.layers", 1, MAX_LAYERS),
    )

    coarse_coding = True
    if "controller" in data:
        ctl = ck.mapping(data["controller"], "controller", {"coarse_coding"}, {"coarse_coding"})
        coarse_coding = ck.boolean(ctl, "coarse_coding", "controller.coarse_coding")

    t = ck.mapping(data["tissue"], "tissue", _TISSUE_KEYS, _TISSUE_KEYS - {"robots"})
    robots = t.get("robots")
    if robots is not None:
        robots = ck.integer(robots, "tissue.robots", 1, MAX_ROBOTS)
    seed = ck.int_triple(t, "seed", "tissue.seed", -MAX_HALF_WIDTH, MAX_HALF_WIDTH)
    if not lattice.contains(seed):
        raise ck.fail("tissue.seed", list(seed), f"lies outside the lattice {lattice}")
    tissue = TissueGene(
        ck.number(t, "replication_probability", "tissue.replication_probability", 0.0, 1.0),
        ck.number(t, "decision_ratio", "tissue.decision_ratio", 0.0, 1.0),
        seed,
        robots,
    )

    raw_cells = data["cells"]
    if not isinstance(raw_cells, list):
        raise ck.fail("cells", type(raw_cells).__name__, "must be a list of cell genes")
    if len(raw_cells) > MAX_GENES:
        raise ck.fail("cells", f"{len(raw_cells)} genes", f"exceeds the limit of {MAX_GENES} genes")
    cells = []
    seen: dict[tuple[int, int, int], int] = {}
    span = 2 * MAX_HALF_WIDTH + MAX_LAYERS
    for i, c in enumerate(raw_cells):
        f = f"cells[{i}]"
        if not isinstance(c, dict):
            raise ck.fail(f, c, "must be a JSON object")
        kind = c.get("kind")
        if kind not in KINDS:
            raise ck.fail(f"{f}.kind", kind, f"must be one of {list(KINDS)}")
        ck.mapping(c, f, _CELL_KEYS, _CELL_KEYS)
        position = ck.int_triple(c, "position", f"{f}.position", -span, span)
        absolute = tuple(seed[a] + position[a] for a in range(3))
        if not lattice.contains(absolute):
            raise ck.fail(
                f"{f}.position",
                list(position),
                f"puts the cell at {list(absolute)}, outside the lattice "
                f"(|l|, |m| <= {lattice.half_width}, 1 <= n <= {lattice.layers})",
            )
        if absolute in seen:
            raise ck.fail(
                f"{f}.position",
                list(position),
                f"the site {list(absolute)} is already taken by cells[{seen[absolute]}]",
            )
        seen[absolute] = i
        cells.append(
            CellGene(
                kind=kind,
                expressed=ck.boolean(c, "expressed", f"{f}.expressed"),
                dead=ck.boolean(c, "dead", f"{f}.dead"),
                position=position,
                replication=ck.number(c, "replication", f"{f}.replication", 0.0, 1.0),
                theta1=ck.number(c, "theta1", f"{f}.theta1"),
                theta2=ck.number(c, "theta2", f"{f}.theta2"),
                k1=ck.integer(c["k1"], f"{f}.k1", 0, 1),
                k2=ck.integer(c["k2"], f"{f}.k2", 0, 1),
                sensor_weights=ck.vector(c, "sensor_weights", f"{f}.sensor_weights", N_SENSORS),
                input_weights=ck.vector(c, "input_weights", f"{f}.input_weights", N_NOMINAL_INPUTS),
                behaviour=ck.integer(c["behaviour"], f"{f}.behaviour", 0, N_BEHAVIOURS - 1),
                concentration=ck.number(c, "concentration", f"{f}.concentration", 0.0),
                extent=ck.int_triple(c, "extent", f"{f}.extent", 0, MAX_EXTENT),
            )
        )
    metadata = data.get("metadata", {})
    if not isinstance(metadata, dict):
        raise ck.fail("metadata", type(metadata).__name__, "must be a JSON object")
    return Genome(tissue, tuple(cells), lattice, coarse_coding, metadata)
