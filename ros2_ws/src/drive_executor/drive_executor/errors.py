"""Errors of the drive executor."""

from __future__ import annotations

from excavation_common.errors import FieldError


class GoalError(FieldError):
    """A drive goal that cannot be run (bad word, bad encoding, non-finite pose)."""
