"""The base error type of the suite: bad input pinned to one field of one file."""

from __future__ import annotations


class FieldError(ValueError):
    """Bad input that can be pinned to one field of one file.

    The message reads ``path: field = value: reason``. Every loader of the project
    (genomes, blueprints, site files, run configurations, node parameters) raises a
    subclass of this.

    Attributes:
        path: File at fault (or a label such as ``<command line>``).
        field: Field path inside it (``cells[3].sensor_weights[2]``).
        value: Offending value (``None`` when missing).
        reason: What is wrong.
    """

    def __init__(self, path: str, field: str, value: object, reason: str) -> None:
        self.path = str(path)
        self.field = field
        self.value = value
        self.reason = reason
        shown = repr(value)
        if len(shown) > 80:
            shown = shown[:77] + "..."
        super().__init__(f"{self.path}: {field} = {shown}: {reason}")
