"""The middleware settings every process of the suite runs with (no rclpy import).

Fast DDS reads its XML profiles once, when a process creates its first participant, from
the file named by ``FASTRTPS_DEFAULT_PROFILES_FILE``. :func:`use_profiles` points that
variable at one of the suite's profile files (beside this module) before ``rclpy.init``;
the process's children (the nodes a trial or ``ant-dome up`` starts, a camera driver
among them) inherit it. A file the user named already is left alone.

Two settings, and why:

* **Reliable writers' heartbeat period 0.1 s** (both files). Fast DDS's default is 3 s, and
  a lost fragment of a large message (a camera frame) is repaired only after the next
  heartbeat (docs/reliability.md, "the soak slowdown").
* **No shared-memory transport on loopback** (``fastdds_loopback.xml``). With
  ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` rmw_fastrtps gives every participant Fast
  DDS's shared-memory transport besides UDP, and ignores the transports of an XML profile.
  A process killed with SIGKILL leaves its shared-memory ports in ``/dev/shm`` in whatever
  state it died in, and a live participant that keeps writing to them (or a new one that
  opens the same port) can crash inside the transport: a segmentation fault in a process
  whose peer was killed (docs/reliability.md, "A killed peer crashed its neighbours").
  So for LOCALHOST the suite names the loopback profile, which carries the same discovery
  rmw_fastrtps configures for LOCALHOST (unicast on 127.0.0.1, localhost as the initial
  peer, no multicast) over UDP alone, and asks rmw to leave the transports to it
  (``ROS_AUTOMATIC_DISCOVERY_RANGE=SYSTEM_DEFAULT``). Traffic still never leaves loopback:
  the UDP transport binds 127.0.0.1 only. With ``ROS_STATIC_PEERS`` set the range is left
  as it is (SYSTEM_DEFAULT would ignore the peers).
"""

from __future__ import annotations

import os
from collections.abc import MutableMapping
from pathlib import Path

PROFILES_FILE = Path(__file__).with_name("fastdds_profiles.xml")
"""The suite's Fast DDS profiles for every discovery range but LOCALHOST (heartbeat 0.1 s)."""

LOOPBACK_PROFILES_FILE = Path(__file__).with_name("fastdds_loopback.xml")
"""The suite's Fast DDS profiles for LOCALHOST: UDP on 127.0.0.1 only, heartbeat 0.1 s."""

PROFILE_VARIABLES = ("FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE")
"""Environment variables by which a user names their own Fast DDS profiles file."""

RANGE_VARIABLE = "ROS_AUTOMATIC_DISCOVERY_RANGE"
"""The ROS 2 discovery range (LOCALHOST, SUBNET, OFF, SYSTEM_DEFAULT)."""


def use_profiles(environ: MutableMapping[str, str] | None = None) -> str:
    """Point Fast DDS at the suite's profiles unless the user named a profiles file.

    With ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` (and no ``ROS_STATIC_PEERS``) the
    environment gets the loopback profile and the range ``SYSTEM_DEFAULT``, so that no
    participant of the suite uses Fast DDS's shared-memory transport (module docstring).
    Calling it again, or on an environment copied from one it set up, changes nothing.

    Args:
        environ: The environment to change (default: this process's ``os.environ``, which
            the Fast DDS library and every child process see).

    Returns:
        The profiles file the environment names now.
    """
    env = os.environ if environ is None else environ
    ours = {str(PROFILES_FILE), str(LOOPBACK_PROFILES_FILE)}
    for name in PROFILE_VARIABLES:
        if env.get(name) and env[name] not in ours:
            return env[name]
    loopback = env.get(RANGE_VARIABLE) == "LOCALHOST" and not env.get("ROS_STATIC_PEERS")
    if env.get(PROFILE_VARIABLES[0]) == str(LOOPBACK_PROFILES_FILE):
        # Set up before (this process or its parent): keep it unless the range was named again.
        loopback = loopback or env.get(RANGE_VARIABLE) == "SYSTEM_DEFAULT"
    profiles = LOOPBACK_PROFILES_FILE if loopback else PROFILES_FILE
    if loopback:
        env[RANGE_VARIABLE] = "SYSTEM_DEFAULT"
    env[PROFILE_VARIABLES[0]] = str(profiles)
    env.pop(PROFILE_VARIABLES[1], None)
    return str(profiles)
