"""Errors raised by the blueprint loaders."""

from __future__ import annotations

from excavation_common.errors import FieldError


class BlueprintError(FieldError):
    """A blueprint file or generator argument is invalid (``path: field = value: reason``)."""
