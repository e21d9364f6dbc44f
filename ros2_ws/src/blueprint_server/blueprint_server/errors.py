"""Errors raised by the blueprint loaders."""

from __future__ import annotations


class BlueprintError(ValueError):
    """A blueprint file or generator argument is invalid.

    Attributes:
        path: File (or generator label) at fault.
        field: Field inside it, dotted (``pit.origin``, ``rows[3]``).
        value: Offending value.
        reason: What is wrong with it.
    """

    def __init__(self, path: str, field: str, value: object, reason: str) -> None:
        self.path = str(path)
        self.field = field
        self.value = value
        self.reason = reason
        super().__init__(f"{self.path}: {field} = {value!r}: {reason}")
