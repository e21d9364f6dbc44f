"""Resource limits for a child process, set in the child itself before it runs its command.

``subprocess``'s ``preexec_fn`` runs Python code between fork and exec, which the Python
documentation calls unsafe when the parent has threads (a test's parent does: a ROS
executor, a watcher, a pool): the child may deadlock before its exec. :func:`limited`
instead prefixes a command with a tiny Python program that sets the limits on itself with
``resource.setrlimit`` and then ``exec``s the command, so the command runs in the same
process (the same pid: signals and exit codes are the command's) with the limits in force.
"""

from __future__ import annotations

import resource
import sys

# Limits as NAME=SOFT:HARD (RLIMIT_NAME), then "--", then the command. SIGPIPE and SIGXFSZ
# go back to their defaults first, as subprocess's restore_signals does before an exec (this
# Python ignores them, and an ignored signal stays ignored across exec).
_SET_LIMITS_THEN_EXEC = """\
import os, resource, signal, sys
args = sys.argv[1:]
split = args.index("--")
for item in args[:split]:
    name, value = item.split("=")
    soft, hard = value.split(":")
    resource.setrlimit(getattr(resource, "RLIMIT_" + name), (int(soft), int(hard)))
for name in ("SIGPIPE", "SIGXFSZ"):
    signal.signal(getattr(signal, name), signal.SIG_DFL)
os.execvp(args[split + 1], args[split + 1:])
"""


def limited(command: list[str], **limits: int) -> list[str]:
    """``command`` as a command line that runs it with ``resource`` limits (soft = hard).

    Args:
        command: The program and its arguments (a name is looked up in ``PATH``).
        limits: Per ``RLIMIT_`` name less the prefix, e.g. ``AS=2 << 30`` (address space,
            bytes) or ``FSIZE=300_000`` (largest file written, bytes).

    Returns:
        A command line for ``subprocess`` (no ``preexec_fn`` needed).
    """
    for name in limits:
        if not hasattr(resource, f"RLIMIT_{name}"):
            raise ValueError(f"no such resource limit: RLIMIT_{name}")
    settings = [f"{name}={value}:{value}" for name, value in limits.items()]
    return [sys.executable, "-c", _SET_LIMITS_THEN_EXEC, *settings, "--", *command]
