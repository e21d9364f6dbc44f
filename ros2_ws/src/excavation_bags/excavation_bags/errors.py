"""Errors of the bag tools; each names the bag (file), the field and the value at fault."""

from __future__ import annotations

from excavation_common.errors import FieldError


class BagError(FieldError):
    """A bag cannot be used as asked: ``bag: field = value: reason``."""


class BagNotFoundError(BagError):
    """No bag directory (or no MCAP file in it) at the given path."""


class BagExistsError(BagError):
    """The output directory of a recording exists already (bags are never overwritten)."""


class BagFormatError(BagError):
    """A bag's metadata.yaml or MCAP file is malformed beyond what can be read back."""


class UnknownTypeError(BagError):
    """A topic's message type is not one the tools know (no definition to decode it)."""


class MissingTopicError(BagError):
    """A topic the asked-for work needs is not in the bag (or has the wrong type)."""
