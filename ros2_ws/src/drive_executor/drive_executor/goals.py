"""The team tick's drive goal and the executor's status of it, as ROS messages.

A goal is an ``excavation_interfaces/DriveGoal``, sent as the goal of the drive action
(``/robot_k/drive``, ``excavation_interfaces/action/Drive``): the tick's stamp and number,
the behaviour word (bit i = behaviour i+1 of Table 2), the random turn's direction and the
robot. The executor reports every goal's status on ``drive/status``
(``excavation_interfaces/DriveStatus``) with the goal: ``STATUS_EXECUTING`` when it starts,
then ``STATUS_SUCCEEDED``, ``STATUS_ABORTED`` or ``STATUS_CANCELED`` (the codes are
``action_msgs/GoalStatus``'s, as the action's result has them).
"""

from __future__ import annotations

from dataclasses import dataclass

from excavation_interfaces.msg import DriveGoal as DriveGoalMsg
from excavation_interfaces.msg import DriveStatus

from drive_executor.errors import GoalError
from excavation_common.messages import DRIVE_ENDED

RIGHT, LEFT = DriveGoalMsg.TURN_RIGHT, DriveGoalMsg.TURN_LEFT
TURNS = (DriveGoalMsg.TURN_DRAW, RIGHT, LEFT)

EXECUTING = DriveStatus.STATUS_EXECUTING
SUCCEEDED = DriveStatus.STATUS_SUCCEEDED
ABORTED = DriveStatus.STATUS_ABORTED
CANCELED = DriveStatus.STATUS_CANCELED
TERMINAL = DRIVE_ENDED


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


def goal_message(goal: DriveGoal) -> DriveGoalMsg:
    """The ``DriveGoal`` message of a goal."""
    msg = DriveGoalMsg(tick=goal.tick, word=goal.word, turn=goal.turn, robot=goal.robot)
    msg.stamp.sec, msg.stamp.nanosec = goal.stamp
    return msg


def goal_from_message(msg: DriveGoalMsg, topic: str = "drive/goal") -> DriveGoal:
    """Read a goal.

    Raises:
        GoalError: A word beyond 12 bits, or an unknown turn direction.
    """
    if msg.word > 0xFFF:
        raise GoalError(topic, "word", msg.word, "has bits beyond the 12 behaviours")
    if msg.turn not in TURNS:
        raise GoalError(topic, "turn", msg.turn, "must be 0 (draw), 1 (right) or -1 (left)")
    return DriveGoal(
        int(msg.tick), int(msg.word), int(msg.turn), int(msg.robot),
        (msg.stamp.sec, msg.stamp.nanosec),
    )  # fmt: skip


def status_message(goal: DriveGoal, status: int) -> DriveStatus:
    """The ``DriveStatus`` of a goal (it carries the goal, so the tick's stamp)."""
    return DriveStatus(goal=goal_message(goal), status=status)
