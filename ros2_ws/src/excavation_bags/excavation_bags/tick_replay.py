"""Tick replay: fresh controllers decide every recorded tick again (``ant-bag play --genome``).

A bag of a trial holds, per tick, what the controllers read and the word each answered
(``/robot_k/behaviour``). :func:`replay_nodes` builds, in one process, a controller per
recorded robot (the genome given, lockstep, in the robot's namespace, on the team tick's
``/tick`` snapshot when the bag has one, with the IMU as the tilt source when the bag has
the robots' IMU) and a lockstep :class:`~excavation_bags.player_node.PlayerNode` that plays
the controllers' inputs tick by tick and waits for their words. :class:`WordLog` keeps the
words the fresh controllers send, and :func:`compare` lines them up with the recorded ones:
with the recorded genome every word must come again; with another, the first tick that
differs is where the two controllers part.

The bag kinds: a lockstep trial (``ant-trial --record``: ticks at ``/clock``), a continuous
trial and ``ant-dome up --sim`` (ticks at ``/team/tick``, inputs on ``/tick/*``, the blade
on ``/robot_k/blade/joint_states`` stamped with the tick), and the dome (the blade on
``/robot_k/blade/tick_state``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from excavation_bags.errors import MissingTopicError
from excavation_common.topics import TICK_PREFIX, tick_remaps

BEHAVIOUR = re.compile(r"^/robot_(\d+)/behaviour$")


def recorded_robots(bag) -> list[int]:
    """Robot indices with a recorded ``/robot_k/behaviour``.

    Raises:
        MissingTopicError: None in the bag.
    """
    robots = sorted(int(m.group(1)) for t in bag.topics if (m := BEHAVIOUR.match(t)))
    if not robots:
        raise MissingTopicError(
            bag.path, "topics", "/robot_*/behaviour", "no controller words to replay against"
        )
    return robots


def controller_inputs(bag, robots: list[int]) -> tuple[list[str], list[str]]:
    """The topics to play into the controllers, and each controller's remaps (``-r`` args).

    On a team-tick bag the controllers read the tick's snapshot (``/tick``), as the trial's
    own controllers did (:func:`excavation_common.topics.tick_remaps`).
    """
    topics = ["/blueprint/*", "/worksite/map_info", "/robot_*/enabled"]
    continuous = f"{TICK_PREFIX}/worksite/height_map" in bag.topics
    if continuous:
        topics += [f"{TICK_PREFIX}/*"]
    else:
        topics += ["/worksite/height_map", "/robot_*/pose", "/robot_*/stuck"]
    dome_blade = any(t.endswith("/blade/tick_state") for t in bag.topics)
    topics.append("/robot_*/blade/tick_state" if dome_blade else "/robot_*/blade/joint_states")
    if any(t.endswith("/imu") for t in bag.topics):
        topics.append("/robot_*/imu")
    remaps = []
    for k in robots:
        if continuous:
            remaps.append(tick_remaps(robots, k, dome_blade))
        elif dome_blade:
            remaps.append([f"/robot_{k}/blade/joint_states:=/robot_{k}/blade/tick_state"])
        else:
            remaps.append([])
    return topics, remaps


@dataclass
class WordLog:
    """The words fresh controllers sent, per robot, in order.

    With each, the sensor vector it was decided on (the 14 input codes,
    ``ControllerCore.codes``).
    """

    words: dict[int, list[int]] = field(default_factory=dict)
    sensors: dict[int, list[list[int]]] = field(default_factory=dict)

    def add(self, k: int, word: int, codes: list[int]) -> None:
        """Robot ``k`` answered ``word`` on sensor codes ``codes``."""
        self.words.setdefault(k, []).append(int(word))
        self.sensors.setdefault(k, []).append([int(c) for c in codes])


def recorded_words(bag, robots: list[int]) -> dict[int, list[int]]:
    """The words the recorded controllers sent, per robot, in bag order."""
    out = {}
    for k in robots:
        topic = f"/robot_{k}/behaviour"
        out[k] = [int(bag.decode(topic, raw).data) for _, _, raw in bag.messages([topic])]
    return out


def compare(
    recorded: dict[int, list[int]],
    replayed: dict[int, list[int]],
    sensors: dict[int, list[list[int]]] | None = None,
) -> dict:
    """Tick by tick: the ticks whose words differ (robot, recorded, replayed, inputs).

    A tick is the n-th word of each robot. Returns ``ticks`` (compared), ``differing``
    (a list of ``{"tick", "robot", "recorded", "replayed", "sensors"}``, the sensor codes
    the fresh controller decided on where ``sensors`` has them), ``first_difference`` (the
    first differing tick or ``None``) and ``missing`` (robots with fewer words replayed than
    recorded, and how many fewer).
    """
    sensors = sensors or {}
    differing = []
    missing = {}
    ticks = 0
    for k, words in recorded.items():
        again = replayed.get(k, [])
        ticks = max(ticks, len(words))
        if len(again) < len(words):
            missing[k] = len(words) - len(again)
        for t, (a, b) in enumerate(zip(words, again, strict=False)):
            if a != b:
                codes = sensors.get(k, [])
                differing.append(
                    {
                        "tick": t,
                        "robot": k,
                        "recorded": a,
                        "replayed": b,
                        "sensors": codes[t] if t < len(codes) else None,
                    }
                )
    differing.sort(key=lambda d: (d["tick"], d["robot"]))
    return {
        "ticks": ticks,
        "differing": differing,
        "first_difference": differing[0]["tick"] if differing else None,
        "missing": missing,
    }


def replay_nodes(bag, controller, context, height_unit: float = 0.05, timeout: float = 30.0):
    """The player, the controllers and the word log of a tick replay of ``bag``.

    Returns ``(player, controllers, log, probe)``; add them all to one executor and spin
    until ``player.finished``.
    """
    import rclpy
    from rclpy.parameter import Parameter
    from std_msgs.msg import UInt16

    from ant_controller.controller_node import ControllerNode
    from excavation_bags.player_node import PlayerNode

    robots = recorded_robots(bag)
    topics, remaps = controller_inputs(bag, robots)
    imu = any(t.endswith("/imu") for t in bag.topics)
    controllers = []
    for k, r in zip(robots, remaps, strict=True):
        params = [
            Parameter("robot_id", value=k),
            Parameter("robots", value=len(robots)),
            Parameter("height_unit", value=float(height_unit)),
            Parameter("lockstep", value=True),
        ]
        if imu:
            params.append(Parameter("tilt_source", value="imu"))
        args = ["--ros-args"] + [a for remap in r for a in ("-r", remap)] if r else None
        controllers.append(
            ControllerNode(
                controller,
                context=context,
                namespace=f"/robot_{k}",
                parameter_overrides=params,
                cli_args=args,
            )
        )
    log = WordLog()
    probe = rclpy.create_node("tick_replay_words", context=context)
    for k, node in zip(robots, controllers, strict=True):
        # the probe runs after the controller published and before its next decision
        probe.create_subscription(
            UInt16,
            f"/robot_{k}/behaviour",
            lambda m, k=k, node=node: log.add(k, m.data, node.core.codes.tolist()),
            1000,
        )
    player = PlayerNode(
        bag,
        context=context,
        parameter_overrides=[
            Parameter("lockstep", value=True),
            Parameter("topics", value=topics),
            Parameter("lockstep_timeout", value=float(timeout)),
        ],
    )
    return player, controllers, log, probe
