"""Errors of the overhead localizer (each names the file or topic, the field and the value)."""

from __future__ import annotations

from excavation_common.errors import FieldError


class LocalizerConfigError(FieldError):
    """A beacon table or camera calibration file that cannot be used."""


class ImageError(FieldError):
    """A camera frame that cannot be used (wrong size, encoding, layout)."""
