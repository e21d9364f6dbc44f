"""A node's parameters in the trial graph: its kind's parameter dataclasses, filled in.

Each node kind declares its parameters once, as frozen dataclasses
(:mod:`excavation_common.params`, named by :mod:`excavation_bringup.kinds`). A
:class:`NodeParams` holds one instance of each, built when the graph is built, so that a
wrong-typed or out-of-range value fails there, naming the node, the parameter and the value,
before any process starts. A node spec function (:mod:`excavation_bringup.nodes`) gives two
sets of values:

* **derived**: what the run fixes (from the site file or ``ant-trial``'s options: grid
  size, topics, robots, seeds, the blueprint). A site's ``overrides:`` may not change them:
  the site's own field is where they are set.
* **tuned**: the mode's or timing profile's choices (the dome's executor tolerances, the
  team tick's waits); a site may override them, as every parameter the graph leaves at its
  default.

The site's ``overrides:`` for the node's kind are then applied to the instances with
:func:`dataclasses.replace` semantics and validated (type, range, choices, the dataclass's
rules across fields); each refused override is kept as a :class:`~excavation_bringup.site.SiteError`
in :attr:`NodeParams.problems` (``overrides.KIND.NAME = value: reason``), so that ``ant-dome
check`` lists them all; :func:`excavation_bringup.graph.build` refuses a graph with any.

A :class:`NodeParams` reads as a mapping of the parameters the graph or the site gave (what
a node's parameter file lists); :meth:`NodeParams.value` reads any declared parameter.

Pure module: no ``rclpy``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Any

from excavation_bringup.kinds import kind as node_kind
from excavation_bringup.site import SiteError
from excavation_common.params import ParameterError, specs, validate


@dataclass(frozen=True, eq=False)
class NodeParams(Mapping[str, Any]):
    """One node's parameters: an instance of each of its kind's parameter dataclasses.

    Attributes:
        groups: The instances, in the kind's declaration order.
        given: The names the graph or the site set, in order (the node's parameter file).
        derived: The names the run fixes (no override may change them).
        problems: The site's overrides refused for this node, one error each.
    """

    groups: tuple[Any, ...] = ()
    given: tuple[str, ...] = ()
    derived: frozenset[str] = frozenset()
    problems: tuple[SiteError, ...] = ()

    @classmethod
    def build(
        cls,
        kind: str,
        node: str,
        derived: Mapping[str, Any],
        tuned: Mapping[str, Any] | None = None,
        overrides: Mapping[str, Any] | None = None,
        where: str = "",
    ) -> NodeParams:
        """The parameters of node ``node`` (of kind ``kind``).

        Args:
            kind: Its node kind (:data:`excavation_bringup.kinds.KINDS`).
            node: Its name in the graph (error messages).
            derived: Values the run fixes.
            tuned: Values of the mode or profile, which ``overrides`` may change.
            overrides: The site's ``overrides:`` for ``kind``.
            where: The site file (error messages).

        Raises:
            excavation_common.params.ParameterError: A derived or tuned value is refused:
                the graph itself is wrong, whatever the site says.
        """
        tuned = dict(tuned or {})
        both = sorted(set(derived) & set(tuned))
        if both:
            raise ParameterError(node, both[0], derived[both[0]], "both derived and tuned")
        classes = node_kind(kind).param_classes()
        owner = {name: c for c in classes for name in specs(c)}
        values = {**tuned, **derived}
        for name, value in values.items():
            if name not in owner:
                raise ParameterError(node, name, value, f"{kind} has no such parameter")
        groups = [
            validate(c, {n: v for n, v in values.items() if owner[n] is c}, node) for c in classes
        ]
        given = list(values)
        problems: list[SiteError] = []
        for index, c in enumerate(classes):
            accepted: dict[str, Any] = {}
            for name, value in (overrides or {}).items():
                if owner.get(name) is not c:
                    if name not in owner and index == 0:
                        problems.append(
                            SiteError(
                                where,
                                f"overrides.{kind}.{name}",
                                value,
                                f"{kind} has no such parameter",
                            )
                        )
                    continue
                if name in derived:
                    problems.append(
                        SiteError(
                            where,
                            f"overrides.{kind}.{name}",
                            value,
                            f"the graph sets it from the site file or the run's options "
                            f"(excavation_bringup.nodes.{kind}): change the site's own field",
                        )
                    )
                    continue
                try:
                    validate(c, dataclasses.asdict(groups[index]) | {name: value}, node)
                except ParameterError as exc:
                    if exc.field == name:
                        problems.append(
                            SiteError(where, f"overrides.{kind}.{name}", value, exc.reason)
                        )
                        continue
                accepted[name] = value
            if not accepted:
                continue
            try:
                groups[index] = validate(c, dataclasses.asdict(groups[index]) | accepted, node)
            except ParameterError as exc:  # a rule across fields
                problems.append(SiteError(where, f"overrides.{kind}", accepted, exc.reason))
                continue
            given += [n for n in accepted if n not in given]
        return cls(tuple(groups), tuple(given), frozenset(derived), tuple(problems))

    def updated(self, node: str, **values: Any) -> NodeParams:
        """These parameters with ``values`` set (validated), as a launcher changes them."""
        groups = list(self.groups)
        for index, group in enumerate(groups):
            own = {n: v for n, v in values.items() if n in specs(type(group))}
            if own:
                groups[index] = validate(type(group), dataclasses.asdict(group) | own, node)
        known = {n for g in groups for n in specs(type(g))}
        unknown = sorted(set(values) - known)
        if unknown:
            raise ParameterError(node, unknown[0], values[unknown[0]], "unknown parameter")
        given = (*self.given, *(n for n in values if n not in self.given))
        return dataclasses.replace(self, groups=tuple(groups), given=given)

    def typed(self, cls: type) -> Any:
        """The instance of parameter dataclass ``cls``.

        Raises:
            KeyError: The node does not declare ``cls``.
        """
        for group in self.groups:
            if type(group) is cls:
                return group
        raise KeyError(f"no {cls.__name__} among {[type(g).__name__ for g in self.groups]}")

    def value(self, name: str) -> Any:
        """Parameter ``name``'s value, given or default.

        Raises:
            KeyError: The node declares no such parameter.
        """
        for group in self.groups:
            if name in specs(type(group)):
                return getattr(group, name)
        raise KeyError(name)

    def ros(self) -> dict[str, Any]:
        """The given parameters as a ROS parameter file holds them (lists, not tuples)."""
        out = {}
        for name in self.given:
            value = self.value(name)
            out[name] = list(value) if isinstance(value, tuple) else value
        return out

    def __getitem__(self, name: str) -> Any:
        if name not in self.given:
            raise KeyError(name)
        return self.value(name)

    def __iter__(self) -> Iterator[str]:
        return iter(self.given)

    def __len__(self) -> int:
        return len(self.given)
