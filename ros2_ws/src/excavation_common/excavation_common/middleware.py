"""The middleware settings every process of the suite runs with (no rclpy import).

Fast DDS reads its XML profiles once, when a process creates its first participant, from
the file named by ``FASTRTPS_DEFAULT_PROFILES_FILE``. :func:`use_profiles` points that
variable at the suite's ``fastdds_profiles.xml`` (beside this module) before ``rclpy.init``;
the process's children (the nodes a trial or ``ant-dome up`` starts, a camera driver
among them) inherit it. A file the user named already is left alone.

Why: a reliable writer's default heartbeat period is 3 s, and a lost fragment of a large
message (a camera frame) is repaired only after the next heartbeat; the profile shortens
it to 0.1 s (docs/reliability.md).
"""

from __future__ import annotations

import os
from collections.abc import MutableMapping
from pathlib import Path

PROFILES_FILE = Path(__file__).with_name("fastdds_profiles.xml")
"""The suite's Fast DDS profiles (reliable writers' heartbeat period 0.1 s)."""

PROFILE_VARIABLES = ("FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE")
"""Environment variables by which a user names their own Fast DDS profiles file."""


def use_profiles(environ: MutableMapping[str, str] | None = None) -> str:
    """Point Fast DDS at the suite's profiles unless a profiles file is named already.

    Args:
        environ: The environment to change (default: this process's ``os.environ``, which
            the Fast DDS library and every child process see).

    Returns:
        The profiles file the environment names now.
    """
    env = os.environ if environ is None else environ
    for name in PROFILE_VARIABLES:
        if env.get(name):
            return env[name]
    env[PROFILE_VARIABLES[0]] = str(PROFILES_FILE)
    return str(PROFILES_FILE)
