"""Topic names that the node graph and the bag tools share (no ``rclpy`` here).

A continuous run's controllers read the team tick's snapshot, republished under
:data:`TICK_PREFIX`, instead of the live poses, height map and U1; in the dome their blade
state is the blade driver's tick-stamped one (:data:`DOME_BLADE_OUT`). The trial graph
(``excavation_bringup.nodes.controller_remaps``) and the tick replay of a bag
(``excavation_bags.tick_replay``) both remap a controller with :func:`tick_remaps`.
"""

from __future__ import annotations

from collections.abc import Iterable

TICK_PREFIX = "/tick"
"""Where the team tick republishes each tick's snapshot."""

DOME_BLADE_OUT = "blade/tick_state"
"""A dome blade driver's tick-stamped state, relative to the robot's namespace."""


def tick_remaps(robots: Iterable[int], k: int, dome_blade: bool) -> list[str]:
    """Robot ``k``'s controller remaps (``from:=to``) onto the tick's snapshot.

    Args:
        robots: Every robot of the team (each one's pose is read from the tick).
        k: The controller's robot.
        dome_blade: The blade state is the dome driver's :data:`DOME_BLADE_OUT`.
    """
    out = [f"/robot_{j}/pose:={TICK_PREFIX}/robot_{j}/pose" for j in robots]
    out.append(f"/worksite/height_map:={TICK_PREFIX}/worksite/height_map")
    out.append(f"/robot_{k}/stuck:={TICK_PREFIX}/robot_{k}/stuck")
    if dome_blade:
        out.append(f"/robot_{k}/blade/joint_states:=/robot_{k}/{DOME_BLADE_OUT}")
    return out


def topic_name_problem(name: str) -> str | None:
    """Why ``name`` is no valid ROS 2 topic name (``None``: it is one).

    The rules rcl checks when a node creates a publisher or subscription (REP 144's
    names): not empty; only letters, digits, ``_``, ``/``, ``~`` and ``{}``; a ``~`` only
    first; no token (between slashes) starting with a digit; no
    ``//`` and no trailing ``/``; braces balanced and not nested. Checked where a name
    is configured (node parameters, site files), so that a bad one is refused with its
    field named instead of crashing the node that would use it.
    """
    if not name:
        return "is empty"
    bad = sorted({c for c in name if not (c.isascii() and (c.isalnum() or c in "_/~{}"))})
    if bad:
        return f"has {''.join(bad)!r}: only letters, digits, _, /, ~ and {{}} may appear"
    if "~" in name[1:]:
        return "has a ~ that is not its first character"
    if name.endswith("/"):
        return "ends with /"
    if "//" in name:
        return "has //"
    depth = 0
    for c in name:
        depth += (c == "{") - (c == "}")
        if depth not in (0, 1):
            return "has unbalanced or nested braces"
    if depth:
        return "has unbalanced braces"
    for token in name.split("/"):
        if token[:1].isdigit():
            return f"has a part that starts with a digit ({token!r})"
    return None


def frame_name_problem(name: str) -> str | None:
    """Why ``name`` is no usable tf2 frame id (``None``: it is one).

    tf2 refuses a frame id with a leading ``/`` (``TF_SELF_TRANSFORM``-style errors at
    every lookup) and tools split on whitespace; here a frame id is letters, digits, ``_``,
    ``-``, ``.`` and ``/`` between parts (``robot_0/base_link``), not empty, with no
    leading, trailing or double ``/``.
    """
    if not name:
        return "is empty"
    bad = sorted({c for c in name if not (c.isascii() and (c.isalnum() or c in "_-./"))})
    if bad:
        return f"has {''.join(bad)!r}: only letters, digits, _, -, . and / may appear"
    if name.startswith("/"):
        return "starts with / (tf2 frame ids do not)"
    if name.endswith("/") or "//" in name:
        return "has an empty part between slashes"
    return None
