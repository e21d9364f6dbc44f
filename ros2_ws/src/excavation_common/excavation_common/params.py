"""Node parameters declared once, as fields of a frozen dataclass (no ``rclpy`` here).

A node's parameters are a frozen dataclass whose fields carry :func:`param` metadata
(description, range, choices, read-only). :func:`excavation_common.ros.declare_params`
declares every field on a node with a matching ``ParameterDescriptor`` and reads the
values back into the dataclass; :func:`validate` checks ranges and choices here, in pure
Python, so a bad value at start gives one :class:`ParameterError` line (exit code 2) and a
bad runtime ``set_parameters`` is rejected with the same reason.

Example::

    @dataclass(frozen=True)
    class ExecutorParams:
        rate: float = param(20.0, "control loop rate, Hz", low=1.0, high=1000.0)
        backend: str = param("sim", "blade backend", choices=("sim", "serial"))

        def check(self) -> None:        # optional cross-field rules
            ...
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field, fields
from typing import Any

from excavation_common.errors import FieldError
from excavation_common.topics import frame_name_problem, topic_name_problem


class ParameterError(FieldError):
    """A node parameter is out of range, of the wrong type or inconsistent.

    The message reads ``node: parameter = value: reason``.
    """


@dataclass(frozen=True)
class ParamSpec:
    """What :func:`param` attaches to a dataclass field.

    Attributes:
        description: One line for ``ParameterDescriptor.description`` and the docs.
        low: Smallest allowed value (numbers), or ``None``.
        high: Largest allowed value (numbers), or ``None``.
        choices: Allowed values (strings), or empty.
        read_only: Read at start only (``ParameterDescriptor.read_only``).
    """

    description: str
    low: float | None = None
    high: float | None = None
    choices: tuple[Any, ...] = ()
    read_only: bool = True


def param(
    default: Any,
    description: str,
    *,
    low: float | None = None,
    high: float | None = None,
    choices: tuple[Any, ...] = (),
    read_only: bool = True,
) -> Any:
    """A dataclass field with a default and a :class:`ParamSpec`.

    Lists are stored as tuples so that the dataclass stays hashable and frozen.
    """
    if isinstance(default, list):
        default = tuple(default)
    spec = ParamSpec(description, low, high, tuple(choices), read_only)
    return field(default=default, metadata={"param": spec})


def specs(cls: type) -> dict[str, ParamSpec]:
    """``{name: ParamSpec}`` of a parameter dataclass, in field order."""
    out = {}
    for f in fields(cls):
        spec = f.metadata.get("param")
        if spec is None:
            raise TypeError(f"{cls.__name__}.{f.name} has no param() metadata")
        out[f.name] = spec
    return out


def defaults(cls: type) -> dict[str, Any]:
    """``{name: default}`` of a parameter dataclass."""
    return {f.name: f.default for f in fields(cls)}


def _coerce(node: str, name: str, default: Any, value: Any) -> Any:
    """``value`` converted to the type of ``default`` (bool, int, float, str, tuple)."""
    kind = type(default)
    if kind is bool:
        if not isinstance(value, bool):
            raise ParameterError(node, name, value, "expected true or false")
        return value
    if kind is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ParameterError(node, name, value, "expected an integer")
        return int(value)
    if kind is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ParameterError(node, name, value, "expected a number")
        if not math.isfinite(float(value)):
            raise ParameterError(node, name, value, "must be finite")
        return float(value)
    if kind is str:
        if not isinstance(value, str):
            raise ParameterError(node, name, value, "expected a string")
        return value
    if kind is tuple:
        if not isinstance(value, list | tuple):
            raise ParameterError(node, name, value, "expected a list")
        return tuple(value)
    raise TypeError(f"parameter {name}: unsupported type {kind.__name__}")


def validate(cls: type, values: dict[str, Any], node: str = "<node>") -> Any:
    """Build ``cls`` from ``values`` (missing names take their default), checking each spec.

    Unknown names are an error, as are values outside ``low .. high`` or ``choices``. The
    dataclass's own ``check()`` (if any) runs last for rules across fields.

    Raises:
        ParameterError: Naming the node, the parameter and the value.
    """
    table = specs(cls)
    unknown = sorted(set(values) - set(table))
    if unknown:
        raise ParameterError(node, unknown[0], values[unknown[0]], "unknown parameter")
    base = defaults(cls)
    out = {}
    for name, spec in table.items():
        value = _coerce(node, name, base[name], values.get(name, base[name]))
        numeric = isinstance(value, int | float) and not isinstance(value, bool)
        if numeric and spec.low is not None and value < spec.low:
            raise ParameterError(node, name, value, f"must be >= {spec.low}")
        if numeric and spec.high is not None and value > spec.high:
            raise ParameterError(node, name, value, f"must be <= {spec.high}")
        if spec.choices and value not in spec.choices:
            raise ParameterError(
                node, name, value, f"must be one of {', '.join(map(str, spec.choices))}"
            )
        if name.endswith("topic") and isinstance(value, str) and value:
            problem = topic_name_problem(value)
            if problem:
                raise ParameterError(node, name, value, f"is not a ROS topic name: {problem}")
        if name.endswith(("frame", "frame_id")) and isinstance(value, str):
            problem = frame_name_problem(value)
            if problem:
                raise ParameterError(node, name, value, f"is not a tf2 frame id: {problem}")
        out[name] = value
    result = cls(**out)
    check = getattr(result, "check", None)
    if check is not None:
        try:
            check()
        except ParameterError:
            raise
        except ValueError as exc:
            raise ParameterError(node, "parameters", "", str(exc)) from None
    return result


def replace(current: Any, changes: dict[str, Any], node: str = "<node>") -> Any:
    """``current`` with ``changes`` applied and validated (a runtime ``set_parameters``).

    Raises:
        ParameterError: A read-only parameter changed, or a value is invalid.
    """
    table = specs(type(current))
    for name in changes:
        if name in table and table[name].read_only:
            raise ParameterError(node, name, changes[name], "read-only: set it at start")
    values = dataclasses.asdict(current)
    values.update(changes)
    return validate(type(current), values, node)
