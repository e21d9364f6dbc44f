"""Signals for commands that must stop on Ctrl-C however they were started."""

from __future__ import annotations

import contextlib
import signal
from collections.abc import Iterator

_received = 0


def _on_sigint(signum: int, frame: object) -> None:
    global _received
    _received += 1
    raise KeyboardInterrupt


def interrupt_on_sigint() -> None:
    """Make SIGINT (Ctrl-C, ``kill -INT``) raise :class:`KeyboardInterrupt` in this process.

    A shell without job control (a script, ``bash -c '... &'``) starts its background
    commands with SIGINT ignored, and Python keeps an inherited ignore; rclpy's own handler,
    which every node on the default context installs, does not. A command that composes
    nodes on a context of its own (``ant-trial`` and the runs built on it) calls this first,
    so that it stops on the same signal as a ``ros2 run`` node would, and runs its nodes
    under :func:`keep_interrupts`.
    """
    signal.signal(signal.SIGINT, _on_sigint)


def interrupted() -> bool:
    """Whether SIGINT has arrived since :func:`interrupt_on_sigint` was called."""
    return _received > 0


@contextlib.contextmanager
def keep_interrupts() -> Iterator[None]:
    """Raise :class:`KeyboardInterrupt` for a :class:`RuntimeError` that a Ctrl-C caused.

    rclpy's C++ bindings turn a :class:`KeyboardInterrupt` raised while they build a
    message into a :class:`RuntimeError` ("Unable to convert call argument '0' to Python
    object"; measured here: about one Ctrl-C in 300 lands there while messages flow). Around
    code that spins rclpy this gives the command the interruption back (exit 130, not an
    error), whichever call the signal landed in.
    """
    try:
        yield
    except RuntimeError:
        if interrupted():
            raise KeyboardInterrupt from None
        raise
