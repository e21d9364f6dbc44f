"""The team tick's drive goal and the executor's status, as common_interfaces messages.

A goal is an ``action_msgs/GoalInfo`` on ``/robot_k/drive/goal``: ``stamp`` is the tick's
stamp and the 16-byte ``goal_id.uuid`` carries what the executor needs:

=======  ===========================================================================
bytes    meaning
=======  ===========================================================================
0..7     tick number (uint64, little endian)
8..9     the behaviour word (uint16, little endian; bit i = behaviour i+1 of Table 2)
10       random-turn direction: 0 = draw from the executor's own generator, 1 = right, 2 = left
11       robot index
12..15   ``b"ANT1"``: the encoding's tag
=======  ===========================================================================

The executor answers on ``drive/status`` (``action_msgs/GoalStatus``) with the same
``goal_info``: ``STATUS_EXECUTING`` when it starts, then ``STATUS_SUCCEEDED`` or
``STATUS_ABORTED``.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from action_msgs.msg import GoalInfo, GoalStatus

from drive_executor.errors import GoalError

TAG = b"ANT1"
RIGHT, LEFT = 1, -1
_DIRECTION_CODE = {0: 0, RIGHT: 1, LEFT: 2}
_CODE_DIRECTION = {v: k for k, v in _DIRECTION_CODE.items()}

EXECUTING = GoalStatus.STATUS_EXECUTING
SUCCEEDED = GoalStatus.STATUS_SUCCEEDED
ABORTED = GoalStatus.STATUS_ABORTED
TERMINAL = (SUCCEEDED, ABORTED, GoalStatus.STATUS_CANCELED)


@dataclass(frozen=True)
class DriveGoal:
    """One tick's word for one robot.

    Attributes:
        tick: Tick number.
        word: Behaviour word (12 bits).
        turn: Random-turn direction: ``RIGHT`` (+1), ``LEFT`` (-1) or 0 (executor draws).
        robot: Robot index.
        stamp: ``(sec, nanosec)`` of the tick.
    """

    tick: int
    word: int
    turn: int = 0
    robot: int = 0
    stamp: tuple[int, int] = (0, 0)


def goal_message(goal: DriveGoal) -> GoalInfo:
    """``GoalInfo`` of a goal."""
    msg = GoalInfo()
    msg.goal_id.uuid = list(
        struct.pack("<QHBB", goal.tick, goal.word, _DIRECTION_CODE[goal.turn], goal.robot) + TAG
    )
    msg.stamp.sec, msg.stamp.nanosec = goal.stamp
    return msg


def goal_from_message(msg: GoalInfo, topic: str = "drive/goal") -> DriveGoal:
    """Decode a goal.

    Raises:
        GoalError: Not this encoding, a word beyond 12 bits, or an unknown direction code.
    """
    raw = bytes(bytearray(msg.goal_id.uuid))
    if len(raw) != 16 or raw[12:] != TAG:
        raise GoalError(topic, "goal_id.uuid", raw.hex(), f"not a drive goal (tag {TAG!r})")
    tick, word, code, robot = struct.unpack("<QHBB", raw[:12])
    if word > 0xFFF:
        raise GoalError(topic, "word", word, "has bits beyond the 12 behaviours")
    if code not in _CODE_DIRECTION:
        raise GoalError(topic, "turn", code, "must be 0, 1 (right) or 2 (left)")
    return DriveGoal(tick, word, _CODE_DIRECTION[code], robot, (msg.stamp.sec, msg.stamp.nanosec))


def status_message(goal: DriveGoal, status: int) -> GoalStatus:
    """``GoalStatus`` of a goal (stamped with its tick)."""
    return GoalStatus(goal_info=goal_message(goal), status=status)
