"""Errors of the emulated drivers, each naming what is wrong and where."""

from __future__ import annotations

from excavation_common.errors import FieldError


class EmulatorConfigError(FieldError):
    """An emulator's parameters contradict each other or the driver it stands in for."""


class TruthError(FieldError):
    """A message from the simulated world (pose, height map, blade state) cannot be used."""


class PtyError(FieldError):
    """The servo board's pseudo-terminal, its link or its path file cannot be set up."""
