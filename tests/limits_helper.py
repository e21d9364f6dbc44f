"""Kept for the modules that still import ``limited`` from here (``tests/test_faults.py``);
the helper is :mod:`helpers.limits` (``from helpers.limits import limited``)."""

from helpers.limits import limited

__all__ = ["limited"]
