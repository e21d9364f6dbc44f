"""The bag player as a ROS node (``ant-bag play``).

Each played topic gets a publisher with the QoS its recorded publishers offered: transient
local when they all did (so latched maps replay latched and late subscribers still get
them), reliable when they all were. Messages go out as their recorded CDR bytes.

Two ways to pace the replay:

* **recorded timing** (default): message i goes out ``(t_i - t_0) / rate`` seconds after
  the start; ``loop`` starts over at the end.
* **lockstep** (``lockstep: true``): as fast as the subscribers take it, for lockstep
  trials. A tick is the run of messages from one ``tick_topic`` message to the next: the
  lockstep simulator publishes ``/clock`` first in every tick, and the team tick of a
  continuous or dome run ``/team/tick`` before its snapshot (``/tick/*``), the default
  where the bag has it. The player publishes one tick, then
  waits until each topic of ``wait_for`` (default: every ``*/behaviour`` topic of the bag
  that is not played) has carried one message, or ``lockstep_timeout`` passes, exactly
  as the simulator node waits for the controllers' commands. Messages before the first
  ``/clock`` (the latched blueprint and map info) go out first, ``startup_period`` before
  the first tick, as the simulator's first tick comes well after the blueprint server's
  maps (a controller drops poses that arrive before the map info). Replaying a trial's
  inputs this way into fresh controllers reproduces their recorded behaviours
  (``tests/test_bag_play.py``).

Options as ``ros2 bag play`` users know them: ``clock`` publishes ``/clock``
(``rosgraph_msgs/Clock``, ``clock_rate`` Hz) with the bag time of the playback position, so
that nodes on ``use_sim_time`` follow the replay (the bag's own ``/clock``, if any, is then
not played); ``start_offset`` starts that many seconds into the bag, the latest message of
each latched topic before it going out first (a late node still gets the maps);
``exclude`` names topics (or globs) not to play. ``bag_time`` is the playback position,
for a progress line.

Camera frames recorded as ``<topic>/compressed`` (``sensor_msgs/CompressedImage``, see
:mod:`excavation_bags.recorder_node`) are played as recorded and, with ``decode_images``
(default), also decoded with OpenCV and published as ``<topic>`` (``sensor_msgs/Image``,
bgr8 or mono8) when the bag has no such raw topic, so a node that takes raw frames (the
localizer) can be fed from the bag. ``topics`` may name either.

The parameters are :class:`PlayerParams` (``config/bag_player.yaml``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from rosbags.interfaces import QosReliability
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import CompressedImage, Image

from excavation_bags.errors import BagError, MissingTopicError
from excavation_bags.images import COMPRESSED_TYPE, compressed_array, fill_raw, raw_topic
from excavation_bags.metadata import latched
from excavation_bags.reader import Bag, open_bag
from excavation_bags.recorder_node import message_class
from excavation_bags.topics import TopicInfo, topic_selected
from excavation_common.params import ParameterError, param
from excavation_common.ros import declare_params, diagnostics


@dataclass(frozen=True)
class PlayerParams:
    """Parameters of the bag player (mirrored in ``config/bag_player.yaml``)."""

    bag: str = param("", "bag directory to play (usually the DIR argument)")
    topics: tuple[str, ...] = param(("",), 'names or globs to play; [""] = every topic')
    rate: float = param(1.0, "playback speed factor (recorded timing)", low=0.01, high=1000.0)
    loop: bool = param(False, "start over at the end", read_only=False)
    lockstep: bool = param(False, "tick by tick, waiting for the replies on wait_for")
    tick_topic: str = param(
        "", 'a lockstep tick starts at each message of this topic; "" = /team/tick if the '
        "bag has it (continuous and dome runs), else /clock (a lockstep trial)",
    )  # fmt: skip
    wait_for: tuple[str, ...] = param(
        ("",), 'reply topics of a lockstep tick; [""] = every */behaviour topic not played'
    )
    lockstep_timeout: float = param(
        10.0,
        "s to wait for the replies of one lockstep tick",
        low=0.01,
        high=3600.0,
        read_only=False,
    )
    startup_period: float = param(
        1.0, "s given to subscribers before the first lockstep tick", low=0.0, high=600.0
    )
    delay: float = param(
        0.5, "s before the first message with recorded timing", low=0.0, high=600.0
    )
    decode_images: bool = param(
        True, "also publish <topic> (Image) decoded from a recorded <topic>/compressed"
    )
    clock: bool = param(False, "publish /clock with the bag time of the playback position")
    clock_rate: float = param(40.0, "Hz of /clock with clock: true", low=0.1, high=1000.0)
    start_offset: float = param(
        0.0, "s into the bag to start (latched topics' last message before it goes first)",
        low=0.0, high=1e6,
    )  # fmt: skip
    exclude: tuple[str, ...] = param(("",), 'names or globs not to play; [""] = none')


def playback_qos(info: TopicInfo) -> QoSProfile:
    """The QoS a player offers for a recorded topic (from its offered profiles)."""
    reliable = bool(info.qos) and all(q.reliability == QosReliability.RELIABLE for q in info.qos)
    transient = latched(info.qos)
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=1 if transient else 100,
        reliability=ReliabilityPolicy.RELIABLE
        if reliable or not info.qos
        else (ReliabilityPolicy.BEST_EFFORT),
        durability=DurabilityPolicy.TRANSIENT_LOCAL if transient else DurabilityPolicy.VOLATILE,
    )


def lockstep_ticks(
    messages: list[tuple[str, int, bytes]], clock_topic: str = "/clock"
) -> list[list[tuple[str, int, bytes]]]:
    """Split messages (bag order) into ticks starting at each ``clock_topic`` message.

    The first group holds what came before the first clock message (may be empty).
    """
    ticks: list[list[tuple[str, int, bytes]]] = [[]]
    for m in messages:
        if m[0] == clock_topic:
            ticks.append([])
        ticks[-1].append(m)
    return ticks


def split_at_replies(tick: list, replies: set[str]) -> tuple[list, list]:
    """A tick's messages before its last reply and after it, the replies left out.

    In a continuous or dome run a tick goes on after the controllers answered (the robots
    move: IMU readings, blade states); those messages must reach fresh controllers after
    they answered, as they did, or a controller could decide on a later reading.
    """
    last = max((i for i, m in enumerate(tick) if m[0] in replies), default=-1)
    if last < 0:  # nothing answered this tick in the recording: all of it before the wait
        return list(tick), []
    before = [m for m in tick[: last + 1] if m[0] not in replies]
    return before, tick[last + 1 :]


class PlayerNode(Node):
    """Republishes a bag."""

    def __init__(self, bag: Bag | None = None, **kwargs) -> None:
        super().__init__(kwargs.pop("node_name", "bag_player"), **kwargs)
        self.params = declare_params(self, PlayerParams, on_change=self._on_params)
        patterns = [t for t in self.params.topics if t]
        excluded = [t for t in self.params.exclude if t]
        if self.params.clock:
            excluded.append("/clock")  # the player's own /clock replaces the recorded one
        if bag is None and not self.params.bag:
            raise ParameterError(
                self.get_fully_qualified_name(), "bag", "", "required: the bag directory to play"
            )
        self.bag = bag if bag is not None else open_bag(self.params.bag)
        self.warnings = list(self.bag.warnings)
        self.publishers_ = {}
        self.decoded = {}  # bag topic X/compressed -> publisher of X (decoded frames)
        for name, info in self.bag.topics.items():
            selected = (not patterns or topic_selected(name, patterns)) and not (
                excluded and topic_selected(name, excluded)
            )
            raw = raw_topic(name) if info.msgtype == COMPRESSED_TYPE else None
            if (
                self.params.decode_images
                and raw is not None
                and raw not in self.bag.topics
                and (selected or topic_selected(raw, patterns))
                and not (excluded and topic_selected(raw, excluded))
            ):
                self.decoded[name] = self.create_publisher(Image, raw, playback_qos(info))
            if not selected:
                continue
            cls = message_class(info.msgtype)
            if cls is None:
                self.warnings.append(f"not playing {name}: unknown type {info.msgtype}")
                continue
            self.publishers_[name] = self.create_publisher(cls, name, playback_qos(info))
        if not self.publishers_ and not self.decoded:
            skipped = [w for w in self.warnings if w.startswith("not playing")]
            raise MissingTopicError(
                self.bag.path,
                "topics",
                patterns or "all",
                "no playable topic in the bag" + (f" ({'; '.join(skipped)})" if skipped else ""),
            )
        for w in self.warnings:
            self.get_logger().warning(w)
        self.decoded_frames = 0
        self.frame_error = ""
        wanted = set(self.publishers_) | set(self.decoded)
        self.tick_topic = ""
        if self.lockstep:
            for name in ("clock", "start_offset"):
                if getattr(self.params, name):
                    raise ParameterError(
                        self.get_fully_qualified_name(), name, getattr(self.params, name),
                        "recorded timing only: a lockstep replay goes tick by tick",
                    )  # fmt: skip
            self.tick_topic = self.params.tick_topic or (
                "/team/tick" if "/team/tick" in self.bag.topics else "/clock"
            )
            if self.tick_topic not in self.bag.topics:
                raise MissingTopicError(
                    self.bag.path,
                    "tick_topic",
                    self.tick_topic,
                    "lockstep replay splits ticks at it (/clock of a lockstep trial, /team/tick "
                    "of a continuous or dome run)",
                )
            wanted.add(self.tick_topic)
            replies = self._reply_topics(patterns)
            wanted |= replies
        self.messages = list(self.bag.messages(wanted))
        if self.params.start_offset > 0.0:
            self.messages = self._from_offset(self.messages, self.params.start_offset)
        self.clock_pub = None
        if self.params.clock:
            self.clock_pub = self.create_publisher(Clock, "/clock", 10)
            self.create_timer(1.0 / self.params.clock_rate, self.publish_clock)
        self.published = 0
        self.finished = False
        self.loops = 0
        self.ticks, self.after = [], []
        if self.lockstep:
            for tick in lockstep_ticks(self.messages, self.tick_topic):
                before, after = split_at_replies(tick, replies)
                self.ticks.append(before)
                self.after.append(after)
            self.messages = [m for m in self.messages if m[0] not in replies]
        self.tick = 0
        self.missed: list[int] = []
        self.replies: set[str] = set()
        self.reply_subs = []
        if self.lockstep:
            self.wait_for = sorted(replies)
            if not self.wait_for:
                self.get_logger().warning(
                    "lockstep: no reply topic to wait for (every */behaviour topic is played or "
                    "none is in the bag); ticks go out back to back"
                )
            for topic in self.wait_for:
                info = self.bag.topics.get(topic)
                cls = message_class(info.msgtype) if info else None
                if cls is None:
                    raise MissingTopicError(
                        self.bag.path, "wait_for", topic, "not in the bag with a known type"
                    )
                self.reply_subs.append(
                    self.create_subscription(
                        cls, topic, lambda _m, t=topic: self.replies.add(t), 100, raw=True
                    )
                )
        self.ready_since: float | None = None
        self.settle_until = 0.0
        self.waiting_since: float | None = None
        self.index = 0
        self.started: float | None = None
        self.created: float | None = None
        self.create_timer(0.001, self.step)
        self.diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.create_timer(1.0, self.publish_diagnostics)

    def _from_offset(self, messages: list, offset: float) -> list:
        """The messages from ``offset`` s after the first on, latched ones before them.

        Each latched topic's latest message before that instant goes first, stamped with it.
        """
        if not messages:
            return messages
        cut = messages[0][1] + int(round(offset * 1e9))
        first = {}
        for topic, ts, raw in messages:
            if ts >= cut:
                break
            if latched(self.bag.topics[topic].qos):
                first[topic] = (topic, cut, raw)
        return list(first.values()) + [m for m in messages if m[1] >= cut]

    def _reply_topics(self, patterns: list[str]) -> set[str]:
        """``wait_for``, or every ``*/behaviour`` topic of the bag that is not played."""
        named = [t for t in self.params.wait_for if t]
        if named:
            return set(named)
        return {
            t
            for t in self.bag.topics
            if t.endswith("/behaviour") and not (patterns and topic_selected(t, patterns))
        }

    @property
    def bag_time(self) -> int | None:
        """The playback position in the bag's time, ns (``None`` for an empty bag).

        Recorded timing: the first message's time until playback starts, then that plus
        the time played times ``rate``; the last message's once finished. Lockstep: the
        time of the last message published.
        """
        if not self.messages:
            return None
        first, last = self.messages[0][1], self.messages[-1][1]
        if self.finished:
            return last
        if self.lockstep:
            # the last message of the last non-empty tick played (ticks already played)
            for i in range(min(self.tick, len(self.ticks)) - 1, -1, -1):
                if self.ticks[i]:
                    return self.ticks[i][-1][1]
            return first
        if self.started is None:
            return first
        played = (time.monotonic() - self.started) * self.rate
        return min(first + int(played * 1e9), last)

    def publish_clock(self) -> None:
        """``/clock`` = :attr:`bag_time` (``clock: true``)."""
        stamp = self.bag_time
        if stamp is None or self.clock_pub is None:
            return
        msg = Clock()
        msg.clock.sec, msg.clock.nanosec = divmod(int(stamp), 1_000_000_000)
        self.clock_pub.publish(msg)

    @property
    def rate(self) -> float:
        """Playback speed factor."""
        return self.params.rate

    @property
    def loop(self) -> bool:
        """Start over at the end."""
        return self.params.loop

    @property
    def lockstep(self) -> bool:
        """Tick by tick (see the module docstring)."""
        return self.params.lockstep

    def _on_params(self, params: PlayerParams) -> None:
        self.params = params  # loop and lockstep_timeout can change while playing

    def publish_diagnostics(self) -> None:
        """OK while playing or done; WARN naming what the bag holds that cannot be played."""
        problems = self.warnings + ([self.frame_error] if self.frame_error else [])
        level = DiagnosticStatus.WARN if problems else DiagnosticStatus.OK
        state = "finished" if self.finished else "playing"
        message = f"{state} {self.bag.path}" + (f"; {'; '.join(problems)}" if problems else "")
        values = {
            "published": self.published,
            "of": len(self.messages),
            "loops": self.loops,
            "decoded_frames": self.decoded_frames,
        }
        self.diag_pub.publish(diagnostics(self, level, message, values))

    def _publish(self, topic: str, raw: bytes) -> None:
        pub = self.publishers_.get(topic)
        if pub is not None:
            pub.publish(raw)
            self.published += 1
        decoded = self.decoded.get(topic)
        if decoded is not None:
            try:
                msg = deserialize_message(raw, CompressedImage)
                image = compressed_array(msg, topic)
            except (BagError, ValueError, TypeError) as exc:
                self.frame_error = f"a frame of {topic} does not decode: {exc}"
                return
            decoded.publish(fill_raw(image, Image(), msg.header))
            self.decoded_frames += 1

    def step(self) -> None:
        """Publish what is due (runs every millisecond)."""
        if self.finished:
            return
        if self.lockstep:
            self._step_lockstep()
        else:
            self._step_timed()

    def _step_timed(self) -> None:
        now = time.monotonic()
        if self.created is None:
            self.created = now
        if now - self.created < self.params.delay:
            return
        if self.started is None:
            self.started = now
        if not self.messages:
            self.finished = True
            return
        t0 = self.messages[0][1]
        while self.index < len(self.messages):
            topic, ts, raw = self.messages[self.index]
            if (ts - t0) / 1e9 / self.rate > now - self.started:
                return
            self._publish(topic, raw)
            self.index += 1
        if self.loop:
            self.index, self.started = 0, None
            self.loops += 1
        else:
            self.finished = True

    def _subscribers_ready(self) -> bool:
        """True when the replay can start without losing messages.

        Every reply topic has a publisher matched to us, and every subscriber of a played
        topic on the graph is matched to its publisher.
        """
        if not all(sub.get_publisher_count() > 0 for sub in self.reply_subs):
            return False
        pubs = list(self.publishers_.values()) + list(self.decoded.values())
        return all(
            pub.get_subscription_count() >= self.count_subscribers(pub.topic) for pub in pubs
        )

    def _step_lockstep(self) -> None:
        now = time.monotonic()
        if self.ready_since is None:
            if not self._subscribers_ready():
                self.get_logger().info(
                    f"waiting for publishers on {self.wait_for} and for subscribers to connect",
                    throttle_duration_sec=5.0,
                )
                return
            self.ready_since = now
        if now - self.ready_since < self.params.startup_period:
            return
        if self.waiting_since is not None:
            done = set(self.wait_for) <= self.replies
            if not done and now - self.waiting_since < self.params.lockstep_timeout:
                return
            if not done:
                missing = sorted(set(self.wait_for) - self.replies)
                self.get_logger().warning(f"tick {self.tick - 1}: no reply on {missing}")
                self.missed.append(self.tick - 1)
            self.waiting_since = None
            for topic, _ts, raw in self.after[self.tick - 1]:
                self._publish(topic, raw)
        if self.tick >= len(self.ticks):
            if self.loop:
                self.tick = 0
                self.loops += 1
            else:
                self.finished = True
                return
        if now < self.settle_until:
            return
        self.replies.clear()
        for topic, _ts, raw in self.ticks[self.tick]:
            self._publish(topic, raw)
        if not self.wait_for or self.tick == 0:  # no reply to wait for: the rest at once
            for topic, _ts, raw in self.after[self.tick]:
                self._publish(topic, raw)
        self.tick += 1
        if self.tick == 1:
            # the group before the first /clock (latched maps) needs no reply, but the
            # subscribers get time to take it before the first tick's inputs arrive
            self.settle_until = now + self.params.startup_period
        elif self.wait_for:
            self.waiting_since = now
