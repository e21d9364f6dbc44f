"""Errors of the blade driver, each naming the source, the field and the value."""

from __future__ import annotations

from excavation_common.errors import FieldError


class DriverConfigError(FieldError):
    """A driver parameter or an operator set-point is out of range."""


class BoardError(Exception):
    """The servo board did not answer, or answered something the protocol does not allow."""


class PortError(BoardError):
    """The serial port cannot be opened or stopped working (unplugged): reopen it."""
