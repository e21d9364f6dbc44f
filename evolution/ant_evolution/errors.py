"""Errors of the evolution package."""

from __future__ import annotations

from excavation_common.errors import FieldError


class ConfigError(FieldError):
    """A run configuration (file or command line) is invalid (``path: field = value: reason``)."""


class CheckpointError(RuntimeError):
    """A checkpoint is missing, corrupt or belongs to another configuration."""

    def __init__(self, path: str, reason: str) -> None:
        self.path = str(path)
        self.reason = reason
        super().__init__(f"{self.path}: {reason}")
