"""Errors of the terrain mapper (every one names the file or topic, the field and the value)."""

from __future__ import annotations

from excavation_common.errors import FieldError


class MapperError(FieldError):
    """Bad mapper input: a configuration, a map file or a scan that cannot be used."""
