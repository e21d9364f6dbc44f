"""Parameter files and parameter tables, generated from the node kinds' parameter dataclasses.

Every node declares its parameters once, as the fields of frozen dataclasses
(:mod:`excavation_common.params`), and :mod:`excavation_bringup.kinds` names each kind's
dataclasses and parameter file. From these two this module writes:

* ``ros2_ws/src/PACKAGE/config/CONFIG`` of every kind that ships one: every parameter at its
  default, its description and its range or choices as a comment, under a header that says
  how to use the file;
* the parameter tables of ``docs/interfaces.md``, one block per kind between
  ``<!-- params:KIND -->`` and ``<!-- /params:KIND -->``; the prose around them is written
  by hand and left alone;
* the table of the site file's fields that set a node's parameter
  (:func:`excavation_bringup.site.node_param`) in ``docs/dome.md``, between
  ``<!-- site:node-params -->`` and ``<!-- /site:node-params -->``.

Usage::

    python -m excavation_bringup.generate           # rewrite what is stale (make params)
    python -m excavation_bringup.generate --check   # exit 1 naming each stale file

Values are written so that YAML (and rcl, which is strict about types) reads back exactly the
dataclass defaults: doubles always with a decimal point, strings always quoted.
"""

from __future__ import annotations

import argparse
import math
import re
import sys
from dataclasses import fields
from pathlib import Path
from typing import Any

from excavation_bringup.kinds import KINDS, NodeKind
from excavation_common.files import write_text_atomic
from excavation_common.params import ParamSpec

ROOT = Path(__file__).resolve().parents[4]
"""The repository root (this file is ``ros2_ws/src/excavation_bringup/excavation_bringup/``)."""

DOCS = Path("docs") / "interfaces.md"
"""The document whose parameter tables are generated, relative to the root."""

COMMAND = "python -m excavation_bringup.generate"

# How each file names its node. `/**` matches the node in every namespace (the per-robot
# nodes run in /robot_k); the perception nodes' files have always been keyed by node name.
NODE_KEY: dict[str, str] = {"localizer": "localizer", "mapper": "mapper"}

# A kind's subcommand, and the arguments of a `ros2 run` line that loads its file ({file}).
SUBCOMMAND: dict[str, str] = {"recorder": " record", "player": " play"}
RUN_ARGS: dict[str, str] = {
    "controller": "--genome best.json --ros-args -r __ns:=/robot_0 --params-file {file}"
    " -p robot_id:=0",
    "blade_driver": "--ros-args -r __ns:=/robot_0 --params-file {file}",
    "executor": "--ros-args -r __ns:=/robot_0 --params-file {file}",
    "localizer": "--ros-args --params-file {file} -p calibration:=camera.yaml",
    "recorder": "--out DIR --ros-args --params-file {file}",
    "player": "DIR --ros-args --params-file {file}",
}

# Further header lines of a kind's file.
NOTES: dict[str, tuple[str, ...]] = {
    "controller": (
        "`/**` matches the controller in every robot namespace: set robot_id (and robots) per",
        "robot on the command line, as above, or in a `/robot_2/controller:` section.",
    ),
    "blade_driver": ("`/**` matches the driver in every robot namespace.",),
    "executor": ("`/**` matches the executor in every robot namespace.",),
    "localizer": (
        "calibration is required (the camera calibration YAML that `calibrate` writes): without",
        "it the node exits with code 2. `ant-dome up` writes a site's values from its site file.",
    ),
    "mapper": ("`ant-dome up` writes a site's values from its site file.",),
    "recorder": (
        "Command-line flags (--out, --topics, --flush-period, --height-unit, --image-codec)",
        "override these.",
    ),
    "player": (
        "Command-line flags (--topics, --rate, --loop, --lockstep, --wait-for, --delay)",
        "override these.",
    ),
}

TYPE_NAMES = {bool: "bool", int: "integer", float: "double", str: "string"}


class GenerateError(Exception):
    """Nothing can be generated: a name declared twice, a missing block, a bad default."""


def fmt_number(value: int | float) -> str:
    """A number as YAML (and rcl) reads it back with its type: doubles with a ``.``."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise GenerateError(f"not a number: {value!r}")
    if isinstance(value, int):
        return str(value)
    if not math.isfinite(value):
        raise GenerateError(f"not a finite number: {value!r}")
    text = repr(value)
    if "e" in text and "." not in text.split("e")[0]:
        mantissa, exponent = text.split("e")
        text = f"{mantissa}.0e{exponent}"  # YAML 1.1 reads 1e-06 as a string
    return text


def fmt_value(value: Any) -> str:
    """A default as a YAML flow scalar or list that reads back as exactly ``value``."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int | float):
        return fmt_number(value)
    if isinstance(value, str):
        return _quote(value)
    if isinstance(value, tuple):
        if not value:
            raise GenerateError("an empty list has no type a parameter file can state")
        return "[" + ", ".join(fmt_value(v) for v in value) + "]"
    raise GenerateError(f"unsupported default {value!r}")


def _quote(text: str) -> str:
    """A double-quoted YAML string (always quoted: ``"*/image_raw"``, ``""``, ``"1.0"``)."""
    out = text.replace("\\", "\\\\").replace('"', '\\"')
    if not out.isprintable():
        raise GenerateError(f"unprintable string default {text!r}")
    return f'"{out}"'


def type_name(value: Any) -> str:
    """The ROS parameter type of a default (``double``, ``string[]``...)."""
    if isinstance(value, tuple):
        return TYPE_NAMES[type(value[0])] + "[]"
    return TYPE_NAMES[type(value)]


def allowed(spec: ParamSpec) -> str:
    """The range or choices of a parameter, as one short phrase (empty: anything)."""
    if spec.choices:
        return "one of " + ", ".join(str(c) for c in spec.choices)
    low, high = spec.low, spec.high
    if low is not None and high is not None:
        return f"{_bound(low)} .. {_bound(high)}"
    if low is not None:
        return f">= {_bound(low)}"
    if high is not None:
        return f"<= {_bound(high)}"
    return ""


def _bound(value: float) -> str:
    """A range bound for people: ``3600`` rather than ``3600.0``."""
    if isinstance(value, float) and value.is_integer() and abs(value) < 1e15:
        return str(int(value))
    return repr(value)


def describe(spec: ParamSpec) -> str:
    """The description, and whether the parameter may be changed while the node runs."""
    if spec.read_only or "runtime" in spec.description:
        return spec.description
    return f"{spec.description} (settable at runtime)"


def rows(kind: NodeKind) -> list[tuple[type, str, Any, ParamSpec]]:
    """``(dataclass, name, default, spec)`` of every parameter of ``kind``, in declaration order.

    Raises:
        GenerateError: Two dataclasses of the kind declare the same name.
    """
    out, seen = [], {}
    for cls in kind.param_classes():
        for f in fields(cls):
            spec = f.metadata.get("param")
            if spec is None:
                raise GenerateError(f"{cls.__name__}.{f.name} has no param() metadata")
            if f.name in seen:
                raise GenerateError(
                    f"{kind.name}: {f.name} is declared by {seen[f.name].__name__} and "
                    f"{cls.__name__}"
                )
            seen[f.name] = cls
            out.append((cls, f.name, f.default, spec))
    return out


def _qualname(cls: type) -> str:
    return f"{cls.__module__}.{cls.__name__}"


def config_path(kind: NodeKind) -> Path:
    """The kind's parameter file, relative to the root."""
    return Path("ros2_ws") / "src" / kind.package / "config" / kind.config


def command(kind: NodeKind) -> str:
    """``ros2 run PACKAGE EXECUTABLE [SUBCOMMAND]`` of ``kind``."""
    return f"ros2 run {kind.package} {kind.executable}{SUBCOMMAND.get(kind.name, '')}"


def run_line(kind: NodeKind) -> str:
    """The ``ros2 run`` line that loads the kind's file."""
    args = RUN_ARGS.get(kind.name, "--ros-args --params-file {file}")
    return f"{command(kind)} {args.format(file=kind.config)}"


def config_text(kind: NodeKind) -> str:
    """The generated parameter file of ``kind``."""
    table = rows(kind)
    classes = list(dict.fromkeys(cls for cls, *_ in table))
    key = NODE_KEY.get(kind.name, "/**")
    sources = [_qualname(cls) for cls in classes]
    head = [
        f"# GENERATED from {sources[0]}",
        *(f"#   and {name}" for name in sources[1:]),
        f"# by `{COMMAND}` (make params): edit the dataclass, not this file.",
        "#",
        f"# Every parameter of `{command(kind)}` at its default,",
        "# with its description and [range or choices].",
        "# Use:",
        f"#   {run_line(kind)}",
        "# or a copy of this file with your own values. A value that is unknown, out of range or",
        "# of the wrong type (write doubles with a decimal point: 1.0) stops the node at start",
        "# with one line naming it (exit code 2).",
        *(f"# {line}" for line in NOTES.get(kind.name, ())),
        f"{key}:",
        "  ros__parameters:",
    ]
    body = []
    pairs = [(cls, f"{name}: {fmt_value(default)}", spec) for cls, name, default, spec in table]
    width = min(max(len(p) for _, p, _ in pairs), 34) + 2
    last = None
    for cls, pair, spec in pairs:
        if len(classes) > 1 and cls is not last:
            body.append(f"    # {_qualname(cls)}")
            last = cls
        note = describe(spec)
        if allowed(spec):
            note += f" [{allowed(spec)}]"
        gap = " " * max(2, width - len(pair))
        body.append(f"    {pair}{gap}# {note}")
    return "\n".join(head + body) + "\n"


def docs_block(kind: NodeKind) -> str:
    """The generated parameter table of ``kind`` for ``docs/interfaces.md``, markers included."""
    table = rows(kind)
    classes = list(dict.fromkeys(cls for cls, *_ in table))
    names = ", then ".join(f"`{_qualname(cls)}`" for cls in classes)
    where = f"`{config_path(kind).as_posix()}`" if kind.config else "no parameter file"
    lines = [
        f"<!-- params:{kind.name} -->",
        f"<!-- generated by `{COMMAND}` (make params): edit the dataclass, not this table -->",
        f"Parameters of `{command(kind)}` ({names}; {where}):",
        "",
        "| parameter | type | default | allowed | description |",
        "|---|---|---|---|---|",
    ]
    for _, name, default, spec in table:
        cells = [
            f"`{name}`",
            type_name(default),
            f"`{fmt_value(default)}`",
            allowed(spec),
            describe(spec),
        ]
        lines.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
    lines += ["", f"<!-- /params:{kind.name} -->"]
    return "\n".join(lines)


BLOCK = re.compile(r"<!-- params:(?P<name>[a-z_]+) -->.*?<!-- /params:(?P=name) -->", re.S)


def docs_text(text: str) -> str:
    """``text`` (``docs/interfaces.md``) with every kind's block regenerated.

    Raises:
        GenerateError: A kind has no block, has two, or a block names no kind.
    """
    found = [m.group("name") for m in BLOCK.finditer(text)]
    unknown = sorted(set(found) - set(KINDS))
    if unknown:
        raise GenerateError(f"{DOCS}: a params block names no node kind: {', '.join(unknown)}")
    for name in KINDS:
        count = found.count(name)
        if count != 1:
            raise GenerateError(
                f"{DOCS}: {count} blocks <!-- params:{name} --> ... <!-- /params:{name} -->"
                " (one expected: put one where the node's parameters are described)"
            )
    return BLOCK.sub(lambda m: docs_block(KINDS[m.group("name")]), text)


SITE_DOCS = Path("docs") / "dome.md"
"""The document whose table of node-parameter site fields is generated, relative to the root."""

SITE_BLOCK = re.compile(r"<!-- site:node-params -->.*?<!-- /site:node-params -->", re.S)


def site_block() -> str:
    """The table of the site's :func:`~excavation_bringup.site.node_param` fields."""
    from excavation_bringup import site as sitefile
    from excavation_bringup.kinds import kind as node_kind
    from excavation_common.params import specs

    lines = [
        "<!-- site:node-params -->",
        f"<!-- generated by `{COMMAND}` (make params): edit the site's dataclass -->",
        "| site field | sets | type | allowed | description |",
        "|---|---|---|---|---|",
    ]
    for name, kind, param in sitefile.node_fields(sitefile.Robot):
        cls = next(c for c in node_kind(kind).param_classes() if param in specs(c))
        spec = specs(cls)[param]
        default = getattr(cls(), param)
        cells = [
            f"`robots[k].{name}`",
            f"`{kind}` `{param}` (robot k's)",
            type_name(default),
            allowed(spec),
            f"{describe(spec)}; unset: `{fmt_value(default)}`",
        ]
        lines.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
    lines.append("<!-- /site:node-params -->")
    return "\n".join(lines)


def site_docs_text(text: str) -> str:
    """``text`` (``docs/dome.md``) with the node-parameter site fields' table regenerated."""
    if len(SITE_BLOCK.findall(text)) != 1:
        raise GenerateError(f"{SITE_DOCS}: one block <!-- site:node-params --> expected")
    return SITE_BLOCK.sub(lambda _: site_block(), text)


def expected(root: Path = ROOT) -> dict[Path, str]:
    """``{path relative to root: generated text}`` of every generated file."""
    out = {config_path(k): config_text(k) for k in KINDS.values() if k.config}
    out[DOCS] = docs_text((root / DOCS).read_text())
    out[SITE_DOCS] = site_docs_text((root / SITE_DOCS).read_text())
    return out


def stale(root: Path = ROOT) -> list[Path]:
    """The generated files (relative to ``root``) whose text differs from what they should be."""
    out = []
    for path, text in expected(root).items():
        full = root / path
        if not full.exists() or full.read_text() != text:
            out.append(path)
    return out


def write(root: Path = ROOT) -> list[Path]:
    """Rewrite every stale generated file; the ones rewritten."""
    changed = []
    for path, text in expected(root).items():
        full = root / path
        if not full.exists() or full.read_text() != text:
            write_text_atomic(full, text)
            changed.append(path)
    return changed


def main(argv: list[str] | None = None) -> int:
    """``python -m excavation_bringup.generate [--check] [--root DIR]``."""
    parser = argparse.ArgumentParser(
        prog=COMMAND, description=__doc__.split("\n\n")[0].replace("\n", " ")
    )
    parser.add_argument(
        "--check", action="store_true", help="write nothing; exit 1 naming each stale file"
    )
    parser.add_argument(
        "--root", type=Path, default=ROOT, help="the repository (default: this checkout)"
    )
    args = parser.parse_args(argv)
    if not (args.root / DOCS).exists():
        print(f"error: no {args.root / DOCS} (give the repository as --root)", file=sys.stderr)
        return 2
    try:
        if args.check:
            old = stale(args.root)
            for path in old:
                print(f"stale: {path.as_posix()} (run `{COMMAND}` or make params)")
            return 1 if old else 0
        for path in write(args.root):
            print(f"wrote {path.as_posix()}")
    except GenerateError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
