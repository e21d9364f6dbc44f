"""Errors raised by the ANT controller core."""

from __future__ import annotations

from excavation_common.errors import FieldError


class GenomeFormatError(FieldError):
    """A genome file (or mapping) is malformed."""
