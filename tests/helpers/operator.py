"""``ant-operator`` (``team_supervisor.operator``) as a separate process."""

from __future__ import annotations

import os
import subprocess
import sys


def operator(domain: int, *args: str, timeout: str = "5") -> subprocess.CompletedProcess:
    """Run ``ant-operator --timeout TIMEOUT ARGS`` on ROS domain ``domain``.

    Args:
        domain: The ROS domain (``ROS_DOMAIN_ID``) of the team to talk to.
        args: The command and its arguments, e.g. ``"disable", "1"``.
        timeout: ``--timeout``: seconds the operator waits for the supervisor's services.

    Returns:
        The finished process (text ``stdout`` and ``stderr``; killed after 120 s).
    """
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain))
    return subprocess.run(
        [sys.executable, "-m", "team_supervisor.operator", "--timeout", timeout, *args],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
