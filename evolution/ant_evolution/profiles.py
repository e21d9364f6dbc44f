"""Profiles: every contested reading of the paper as a named switch, set together.

The first world model and GA took readings of the paper
that a careful reader contests. Each reading is one switch of a run's configuration
(:class:`ant_evolution.evolve.EvolveConfig`, ``config.yaml``) and of ``ant-eval`` /
``ant-sweep`` / ``ant-experiment`` (``--profile``, ``--set KEY=VALUE``):

| switch | ``v1`` | ``paper`` | where it acts |
|---|---|---|---|
| ``soil_fill`` | false | true | blade equations (:mod:`excavation_sim.rules`) |
| ``normal_load`` | 12 | 24 | push capacity without throttle-up |
| ``throttle_load`` | 24 | 24 | push capacity with throttle-up |
| ``normal_climb`` | 1 | 1 | step the wheels climb without throttle-up |
| ``throttle_climb`` | 2 | 2 | step the wheels climb with throttle-up |
| ``h1`` | relative | absolute | H1 (:mod:`ant_controller.readings`) |
| ``placement`` | anywhere | worksite | where robots start |
| ``site`` | shared | fitted | the default pit's grid (16 x 16, or pit + dump band) |
| ``hand_coded`` | chain | union | the appendix's rules (:mod:`ant_controller.hand_coded`) |
| ``mutation_scope`` | parameter | gene | what p_m is per (:mod:`ant_evolution.ga`) |
| ``mutation_operator`` | redraw | perturb | full-range redraw or bounded perturbation |
| ``mutation_width`` | 0.1 | 0.1 | perturbation half-width, fraction of the range |
| ``elitism`` | 1 | 0 | best genomes copied unchanged |
| ``replication_parent`` | max | proportional | parent of a new cell |
| ``neat_activation`` | sigmoid | modular | NEAT's node activation (``neat_baseline``) |
| ``neat_budget`` | library | ant | NEAT's mutation rates: neat-python's, or ANT's |

``v1`` keeps the readings the shipped genome and every recorded result were made under
(they reproduce bit for bit); ``paper`` is the literal reading. A profile sets every
switch; a key given after it (in ``config.yaml`` or with ``--set``) overrides one.
"""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Iterable, Mapping

import yaml

from ant_controller.readings import CONTROLLER_PROFILES, H1_FRAMES, HAND_CODED_READINGS
from ant_evolution.errors import ConfigError
from ant_evolution.ga import MUTATION_OPERATORS, MUTATION_SCOPES, REPLICATION_PARENTS
from excavation_sim.rules import PLACEMENTS, SITES, WORLD_PROFILES, WorldRules

WORLD_SWITCHES = tuple(f.name for f in dataclasses.fields(WorldRules))
CONTROLLER_SWITCHES = ("hand_coded",)
GA_SWITCHES = (
    "mutation_scope",
    "mutation_operator",
    "mutation_width",
    "elitism",
    "replication_parent",
)
NEAT_SWITCHES = ("neat_activation", "neat_budget")
SWITCHES = WORLD_SWITCHES + CONTROLLER_SWITCHES + GA_SWITCHES + NEAT_SWITCHES
"""Every switch, in documentation order."""

NEAT_ACTIVATIONS = ("sigmoid", "modular")
NEAT_BUDGETS = ("library", "ant")
CHOICES: dict[str, tuple] = {
    "h1": tuple(H1_FRAMES),
    "placement": PLACEMENTS,
    "site": SITES,
    "hand_coded": HAND_CODED_READINGS,
    "mutation_scope": MUTATION_SCOPES,
    "mutation_operator": MUTATION_OPERATORS,
    "replication_parent": REPLICATION_PARENTS,
    "neat_activation": NEAT_ACTIVATIONS,
    "neat_budget": NEAT_BUDGETS,
}
"""Allowed values of each switch that takes a name."""


def _profile(name: str, ga: dict, neat: dict) -> dict:
    values = WORLD_PROFILES[name].to_dict()
    values["hand_coded"] = CONTROLLER_PROFILES[name].hand_coded
    values.update(ga)
    values.update(neat)
    return {k: values[k] for k in SWITCHES}


PROFILES: dict[str, dict] = {
    "v1": _profile(
        "v1",
        {
            "mutation_scope": "parameter",
            "mutation_operator": "redraw",
            "mutation_width": 0.1,
            "elitism": 1,
            "replication_parent": "max",
        },
        {"neat_activation": "sigmoid", "neat_budget": "library"},
    ),
    "paper": _profile(
        "paper",
        {
            "mutation_scope": "gene",
            "mutation_operator": "perturb",
            "mutation_width": 0.1,
            "elitism": 0,
            "replication_parent": "proportional",
        },
        {"neat_activation": "modular", "neat_budget": "ant"},
    ),
}
"""Switch values of each profile (names: :data:`ant_controller.readings.PROFILE_NAMES`)."""


def profile_switches(name: str, label: str = "<arguments>") -> dict:
    """A copy of profile ``name``'s switch values.

    Raises:
        ConfigError: For an unknown profile.
    """
    if name not in PROFILES:
        raise ConfigError(label, "profile", name, f"must be one of {list(PROFILES)}")
    return dict(PROFILES[name])


def world_rules_of(values: Mapping) -> WorldRules:
    """The :class:`WorldRules` of a mapping holding (at least) the world switches.

    Raises:
        ConfigError: For a value out of range (the message names the switch).
    """
    try:
        return WorldRules(**{k: values[k] for k in WORLD_SWITCHES})
    except ValueError as exc:  # RulesError is a FieldError (a ValueError)
        field = getattr(exc, "field", "rules")
        raise ConfigError("<config>", field, getattr(exc, "value", None), str(exc)) from None


def assignment(text: str) -> tuple[str, object]:
    """``KEY=VALUE`` of ``--set`` (an ``argparse`` type): the value read as a YAML scalar.

    ``soil_fill=true``, ``normal_load=24``, ``mutation_scope=gene``.

    Raises:
        argparse.ArgumentTypeError: Without ``=``, with an empty key or a bad value.
    """
    key, sep, value = text.partition("=")
    key = key.strip()
    if not sep or not key:
        raise argparse.ArgumentTypeError(f"{text!r}: use KEY=VALUE (a switch of docs/evolution.md)")
    if key not in SWITCHES:
        raise argparse.ArgumentTypeError(f"{key!r} is not a switch (known: {', '.join(SWITCHES)})")
    try:
        parsed = yaml.safe_load(value) if value.strip() else ""
    except yaml.YAMLError:
        raise argparse.ArgumentTypeError(f"{text!r}: the value is not a YAML scalar") from None
    return key, parsed


def apply_assignments(
    values: Mapping, assignments: Iterable[tuple[str, object]], label: str = "<command line>"
) -> dict:
    """``values`` (every switch) with ``assignments`` applied, each of the switch's type.

    Raises:
        ConfigError: An unknown switch, a value of the wrong type or out of range.
    """
    out = dict(values)
    for key, value in assignments:
        if key not in out:
            raise ConfigError(label, key, value, f"is not a switch (known: {', '.join(SWITCHES)})")
        default = out[key]
        if isinstance(default, bool):
            ok = isinstance(value, bool)
        elif isinstance(default, float):
            ok = isinstance(value, int | float) and not isinstance(value, bool)
            value = float(value) if ok else value
        else:
            ok = isinstance(value, type(default)) and not isinstance(value, bool)
        if not ok:
            raise ConfigError(label, key, value, f"must be like {default!r}")
        if key in CHOICES and value not in CHOICES[key]:
            raise ConfigError(label, key, value, f"must be one of {CHOICES[key]}")
        out[key] = value
    world_rules_of(out)
    return out


def resolve_switches(
    profile: str, assignments: Iterable[tuple[str, object]] = (), label: str = "<command line>"
) -> dict:
    """Profile ``profile``'s switches with ``assignments`` applied (tools without a config).

    Raises:
        ConfigError: An unknown profile or switch, or a bad value.
    """
    return apply_assignments(profile_switches(profile, label), assignments, label)


def add_profile_options(parser: argparse.ArgumentParser, default: str | None = "v1") -> None:
    """Declare ``--profile NAME`` and ``--set KEY=VALUE`` (repeatable), the same on every command.

    They land in ``args.profile`` and ``args.assignments``; :func:`switches_of` resolves them.

    Args:
        parser: The command's parser.
        default: The profile without ``--profile``; ``None`` leaves it to a configuration
            file (``ant-evolve --config``, else ``v1``).
    """
    fallback = "v1" if default is None else default
    where = "" if default is not None else "the configuration file's, else "
    parser.add_argument(
        "--profile",
        choices=tuple(PROFILES),
        default=default,
        help=f"readings of the paper (docs/evolution.md, 'Profiles'): {' or '.join(PROFILES)}; "
        f"default {where}{fallback}",
    )
    parser.add_argument(
        "--set",
        dest="assignments",
        action="append",
        type=assignment,
        default=[],
        metavar="KEY=VALUE",
        help="override one switch of the profile (repeatable), e.g. soil_fill=false",
    )


def switches_of(args: argparse.Namespace, label: str = "<command line>") -> dict:
    """Every switch of ``--profile`` with the ``--set`` overrides (:func:`add_profile_options`).

    Raises:
        ConfigError: A value of the wrong type or out of range; the message names the
            switch and the value (``<command line>: soil_fill = 3: must be like False``).
    """
    return resolve_switches(args.profile, args.assignments, label)
