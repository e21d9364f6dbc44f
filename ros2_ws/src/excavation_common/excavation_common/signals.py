"""Signals for commands that must stop on Ctrl-C however they were started."""

from __future__ import annotations

import signal


def interrupt_on_sigint() -> None:
    """Make SIGINT (Ctrl-C, ``kill -INT``) raise :class:`KeyboardInterrupt` in this process.

    A shell without job control (a script, ``bash -c '... &'``) starts its background
    commands with SIGINT ignored, and Python keeps an inherited ignore; rclpy's own handler,
    which every node on the default context installs, does not. A command that composes
    nodes on a context of its own (``ant-trial`` and the runs built on it) calls this first,
    so that it stops on the same signal as a ``ros2 run`` node would.
    """
    signal.signal(signal.SIGINT, signal.default_int_handler)
