"""Errors of the evolution package."""

from __future__ import annotations


class ConfigError(ValueError):
    """A run configuration (file or command line) is invalid.

    Attributes:
        path: Config file (or ``<config>``).
        field: Key at fault.
        value: Its value.
        reason: What is wrong.
    """

    def __init__(self, path: str, field: str, value: object, reason: str) -> None:
        self.path = str(path)
        self.field = field
        self.value = value
        self.reason = reason
        super().__init__(f"{self.path}: {field} = {value!r}: {reason}")


class CheckpointError(RuntimeError):
    """A checkpoint is missing, corrupt or belongs to another configuration."""

    def __init__(self, path: str, reason: str) -> None:
        self.path = str(path)
        self.reason = reason
        super().__init__(f"{self.path}: {reason}")
