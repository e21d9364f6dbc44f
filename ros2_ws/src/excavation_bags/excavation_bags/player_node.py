"""The bag player as a ROS node (``ant-bag play``).

Each played topic gets a publisher with the QoS its recorded publishers offered: transient
local when they all did (so latched maps replay latched and late subscribers still get
them), reliable when they all were. Messages go out as their recorded CDR bytes.

Two ways to pace the replay:

* **recorded timing** (default): message i goes out ``(t_i - t_0) / rate`` seconds after
  the start; ``loop`` starts over at the end.
* **lockstep** (``lockstep: true``): as fast as the subscribers take it, for lockstep
  trials. A tick is the run of messages from one ``/clock`` message to the next (the
  simulator publishes ``/clock`` first in every tick). The player publishes one tick, then
  waits until each topic of ``wait_for`` (default: every ``*/behaviour`` topic of the bag
  that is not played) has carried one message, or ``lockstep_timeout`` passes, exactly
  as the simulator node waits for the controllers' commands. Messages before the first
  ``/clock`` (the latched blueprint and map info) go out first, ``startup_period`` before
  the first tick, as the simulator's first tick comes well after the blueprint server's
  maps (a controller drops poses that arrive before the map info). Replaying a trial's
  inputs this way into fresh controllers reproduces their recorded behaviours
  (``tests/test_bag_play.py``).

Parameters: ``bag`` (directory), ``topics`` (names or globs; default all), ``rate`` (1.0),
``loop`` (false), ``lockstep`` (false), ``wait_for`` (topics), ``lockstep_timeout`` (10.0 s;
a reply lost and re-sent by the middleware can take a few seconds),
``startup_period`` (1.0 s: in lockstep mode, time given to the subscribers after every
``wait_for`` topic has a publisher), ``delay`` (0.5 s: with recorded timing, time given to
subscribers to connect before the first message).
"""

from __future__ import annotations

import time

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosbags.interfaces import QosReliability

from excavation_bags.errors import BagError, MissingTopicError
from excavation_bags.recorder_node import message_class
from excavation_bags.storage import Bag, TopicInfo, latched, open_bag, topic_selected
from excavation_common.ros import diagnostics


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


class PlayerNode(Node):
    """Republishes a bag."""

    def __init__(self, bag: Bag | None = None, **kwargs) -> None:
        super().__init__(kwargs.pop("node_name", "bag_player"), **kwargs)
        p = self.declare_parameter
        path = str(p("bag", "").value)
        patterns = [t for t in p("topics", [""]).value if t]
        self.rate = float(p("rate", 1.0).value)
        self.loop = bool(p("loop", False).value)
        self.lockstep = bool(p("lockstep", False).value)
        wait_for = [t for t in p("wait_for", [""]).value if t]
        self.lockstep_timeout = float(p("lockstep_timeout", 10.0).value)
        self.startup_period = float(p("startup_period", 1.0).value)
        self.delay = float(p("delay", 0.5).value)
        self.bag = bag if bag is not None else open_bag(path)
        if not self.rate > 0:
            raise BagError(self.bag.path, "rate", self.rate, "must be > 0")
        self.warnings = list(self.bag.warnings)
        self.publishers_ = {}
        for name, info in self.bag.topics.items():
            if patterns and not topic_selected(name, patterns):
                continue
            cls = message_class(info.msgtype)
            if cls is None:
                self.warnings.append(f"not playing {name}: unknown type {info.msgtype}")
                continue
            self.publishers_[name] = self.create_publisher(cls, name, playback_qos(info))
        if not self.publishers_:
            skipped = [w for w in self.warnings if w.startswith("not playing")]
            raise MissingTopicError(
                self.bag.path,
                "topics",
                patterns or "all",
                "no playable topic in the bag" + (f" ({'; '.join(skipped)})" if skipped else ""),
            )
        for w in self.warnings:
            self.get_logger().warning(w)
        wanted = set(self.publishers_)
        if self.lockstep:
            wanted.add("/clock")
            if "/clock" not in self.bag.topics:
                raise MissingTopicError(
                    self.bag.path, "topics", "/clock", "lockstep replay splits ticks at /clock"
                )
        self.messages = list(self.bag.messages(wanted))
        self.published = 0
        self.finished = False
        self.loops = 0
        self.ticks = lockstep_ticks(self.messages) if self.lockstep else []
        self.tick = 0
        self.replies: set[str] = set()
        self.reply_subs = []
        if self.lockstep:
            self.wait_for = wait_for or [
                t for t in self.bag.topics if t.endswith("/behaviour") and t not in self.publishers_
            ]
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

    def publish_diagnostics(self) -> None:
        """OK while playing or done; WARN naming what the bag holds that cannot be played."""
        level = DiagnosticStatus.WARN if self.warnings else DiagnosticStatus.OK
        state = "finished" if self.finished else "playing"
        message = f"{state} {self.bag.path}" + (
            f"; {'; '.join(self.warnings)}" if self.warnings else ""
        )
        values = {"published": self.published, "of": len(self.messages), "loops": self.loops}
        self.diag_pub.publish(diagnostics(self, level, message, values))

    def _publish(self, topic: str, raw: bytes) -> None:
        pub = self.publishers_.get(topic)
        if pub is not None:
            pub.publish(raw)
            self.published += 1

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
        if now - self.created < self.delay:
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
        return all(
            pub.get_subscription_count() >= self.count_subscribers(topic)
            for topic, pub in self.publishers_.items()
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
        if now - self.ready_since < self.startup_period:
            return
        if self.waiting_since is not None:
            done = set(self.wait_for) <= self.replies
            if not done and now - self.waiting_since < self.lockstep_timeout:
                return
            if not done:
                missing = sorted(set(self.wait_for) - self.replies)
                self.get_logger().warning(f"tick {self.tick - 1}: no reply on {missing}")
            self.waiting_since = None
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
        self.tick += 1
        if self.tick == 1:
            # the group before the first /clock (latched maps) needs no reply, but the
            # subscribers get time to take it before the first tick's inputs arrive
            self.settle_until = now + self.startup_period
        elif self.wait_for:
            self.waiting_since = now
