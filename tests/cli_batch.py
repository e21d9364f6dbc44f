"""Run one command line's ``main`` for many argument lists in this one process.

``tests/test_broken_inputs.py`` starts it (memory-capped) once per command instead of one
process per input file. It reads a JSON request on stdin::

    {"entry": "package.module:main", "prog": "ant-eval", "calls": [[ARG, ...], ...],
     "timeout": SECONDS}

imports ``main`` and, for each argument list in turn, sets ``sys.argv`` and calls
``main()`` as the console script does (``sys.exit(main())``): a ``SystemExit`` gives the
exit code, any other exception is printed as Python prints an uncaught one (a traceback)
and gives exit code 1, and a call still running after ``timeout`` seconds is interrupted
(``SIGALRM``). File descriptors 1 and 2 of each call go to files of their own, so a call's
output is everything the process wrote during it, from Python or from C. After each call
one JSON line goes to the original stdout:
``{"index": I, "returncode": CODE or null (timed out), "stdout": END, "stderr": ...}``
(``END``: the last 4000 characters).
"""

from __future__ import annotations

import importlib
import json
import os
import signal
import sys
import tempfile
import traceback


class CallTimeout(BaseException):
    """Raised in a call that outlived its time (by ``SIGALRM``)."""


def _on_alarm(signum, frame) -> None:
    raise CallTimeout


def exit_code(value) -> int:
    """The exit status of ``sys.exit(value)`` (a non-integer is printed to stderr: 1)."""
    if value is None:
        return 0
    if isinstance(value, int):
        return value
    print(value, file=sys.stderr)
    return 1


def call(main, prog: str, argv: list[str], timeout: int) -> tuple[int | None, str, str]:
    """``main()`` with ``sys.argv = [prog, *argv]``: (exit code or None, stdout, stderr)."""
    sys.argv = [prog, *argv]
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        sys.stdout.flush()
        sys.stderr.flush()
        saved = os.dup(1), os.dup(2)
        os.dup2(out.fileno(), 1)
        os.dup2(err.fileno(), 2)
        signal.alarm(timeout)
        try:
            try:
                code = exit_code(main())
            except SystemExit as stop:
                code = exit_code(stop.code)
            except CallTimeout:
                code = None
            except BaseException:  # what an uncaught exception does: traceback, exit code 1
                traceback.print_exc()
                code = 1
        finally:
            signal.alarm(0)
            sys.stdout.flush()
            sys.stderr.flush()
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            os.close(saved[0])
            os.close(saved[1])
        out.seek(0)
        err.seek(0)
        stdout = out.read().decode(errors="replace")
        stderr = err.read().decode(errors="replace")
    return code, stdout, stderr


def run() -> int:
    """Read the request, make every call, report each as it ends."""
    request = json.load(sys.stdin)
    with open(os.devnull, "rb") as null:  # a call reads no stdin (as the tests' runs did not)
        os.dup2(null.fileno(), 0)
    report = os.fdopen(os.dup(1), "w", buffering=1)
    signal.signal(signal.SIGALRM, _on_alarm)
    module, name = request["entry"].split(":")
    main = getattr(importlib.import_module(module), name)
    for index, argv in enumerate(request["calls"]):
        code, stdout, stderr = call(main, request["prog"], argv, int(request["timeout"]))
        line = {"index": index, "returncode": code, "stdout": stdout[-4000:], "stderr": stderr}
        report.write(json.dumps(line) + "\n")
    report.close()
    return 0


if __name__ == "__main__":
    sys.exit(run())
