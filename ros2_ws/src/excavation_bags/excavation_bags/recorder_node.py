"""The bag recorder as a ROS node (``ant-bag record``; composable on a trial's executor).

The node looks for matching topics on the graph every ``discovery_period`` seconds and
subscribes to each new one with a QoS that fits its publishers, the way ``ros2 bag record``
does: transient local when every publisher offers it (so latched maps published before the
recorder started are still recorded), reliable when every publisher is reliable. Messages
are stored as the CDR bytes the middleware delivers (``raw=True``), stamped with the time
the publisher sent them (the DDS source timestamp): the bag keeps the publishers' order even
when the recorder runs late. Each topic's offered QoS profiles go into the bag.

Every ``flush_period`` seconds the writer closes its MCAP chunk and rewrites
``metadata.yaml`` (see :mod:`excavation_bags.storage`), so a crash loses at most that
much. :meth:`RecorderNode.close` finishes the bag; call it before destroying the node.

Parameters: ``out`` (bag directory, required), ``topics`` (names or globs; default: every
suite topic, :data:`~excavation_bags.storage.SUITE_TOPICS`), ``flush_period`` (0.5 s),
``discovery_period`` (0.1 s), ``depth`` (queue depth per subscription, 100),
``height_unit`` (metres per soil unit, stored in the bag for the report; 0.05).
"""

from __future__ import annotations

import importlib

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from excavation_bags.errors import UnknownTypeError
from excavation_bags.storage import (
    SUITE_TOPICS,
    BagWriter,
    qos_from_profile,
    topic_selected,
    typestore,
)
from excavation_common.ros import diagnostics


def message_class(msgtype: str):
    """The rclpy message class of ``pkg/msg/Name``, or ``None`` when it is not installed."""
    try:
        pkg, kind, name = msgtype.split("/")
        return getattr(importlib.import_module(f"{pkg}.{kind}"), name)
    except (ValueError, ImportError, AttributeError):
        return None


class RecorderNode(Node):
    """Records matching topics into a bag directory."""

    def __init__(self, custom_data: dict[str, str] | None = None, **kwargs) -> None:
        super().__init__(kwargs.pop("node_name", "bag_recorder"), **kwargs)
        p = self.declare_parameter
        out = str(p("out", "").value)
        topics = list(p("topics", [""]).value)
        self.patterns = [t for t in topics if t] or list(SUITE_TOPICS)
        self.depth = int(p("depth", 100).value)
        flush_period = float(p("flush_period", 0.5).value)
        discovery_period = float(p("discovery_period", 0.1).value)
        height_unit = float(p("height_unit", 0.05).value)
        if not out:
            raise ValueError("recorder: parameter out (bag directory) is required")
        extra = {"height_unit": repr(height_unit), **(custom_data or {})}
        self.writer = BagWriter(out, extra)
        self.skipped: dict[str, str] = {}
        self.received = 0
        self._subs = {}
        self.discover()
        self.create_timer(discovery_period, self.discover)
        self.create_timer(flush_period, self.flush)
        self.diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.create_timer(1.0, self.publish_diagnostics)

    def publish_diagnostics(self) -> None:
        """OK while recording; WARN naming the topics it cannot record."""
        if self.writer.closed:
            return
        skipped = "; ".join(f"{t}: {why}" for t, why in self.skipped.items())
        level = DiagnosticStatus.WARN if skipped else DiagnosticStatus.OK
        message = f"recording {len(self._subs)} topics" + (
            f"; not recorded: {skipped}" if skipped else ""
        )
        values = {
            "messages": self.received,
            "topics": len(self._subs),
            "skipped": len(self.skipped),
        }
        self.diag_pub.publish(diagnostics(self, level, message, values))

    def discover(self) -> None:
        """Subscribe to matching topics that appeared since the last look."""
        if self.writer.closed:
            return
        for topic, types in self.get_topic_names_and_types():
            if topic in self._subs or topic in self.skipped:
                continue
            if not topic_selected(topic, self.patterns):
                continue
            msgtype = types[0]
            cls = message_class(msgtype)
            if cls is None or msgtype not in typestore().types:
                self.skipped[topic] = f"unknown type {msgtype}"
                self.get_logger().warning(f"not recording {topic}: unknown type {msgtype}")
                continue
            infos = self.get_publishers_info_by_topic(topic)
            offered = [qos_from_profile(i.qos_profile) for i in infos]
            if not offered:
                continue  # the publisher left again; look next time
            try:
                self.writer.add_topic(topic, msgtype, offered)
            except UnknownTypeError as exc:
                self.skipped[topic] = str(exc)
                continue
            profiles = [i.qos_profile for i in infos]
            qos = QoSProfile(
                history=HistoryPolicy.KEEP_LAST,
                depth=self.depth,
                reliability=(
                    ReliabilityPolicy.RELIABLE
                    if all(q.reliability == ReliabilityPolicy.RELIABLE for q in profiles)
                    else ReliabilityPolicy.BEST_EFFORT
                ),
                durability=(
                    DurabilityPolicy.TRANSIENT_LOCAL
                    if all(q.durability == DurabilityPolicy.TRANSIENT_LOCAL for q in profiles)
                    else DurabilityPolicy.VOLATILE
                ),
            )
            self._subs[topic] = self.create_subscription(
                cls, topic, lambda raw, info, t=topic: self.on_message(t, raw, info), qos, raw=True
            )

    def on_message(self, topic: str, raw: bytes, info: dict) -> None:
        """Store one message, stamped with its source (publish) time."""
        if self.writer.closed:
            return
        stamp = int(info.get("source_timestamp") or 0) or self.get_clock().now().nanoseconds
        self.writer.write(topic, stamp, raw)
        self.received += 1

    def flush(self) -> None:
        """Make what was received so far survive a crash."""
        if not self.writer.closed:
            self.writer.flush()

    @property
    def recorded(self) -> dict[str, int]:
        """Messages recorded per topic."""
        return {t.name: t.count for t in self.writer.topics.values()}

    def close(self) -> None:
        """Finish the bag (MCAP summary and final metadata.yaml)."""
        for sub in self._subs.values():
            self.destroy_subscription(sub)
        self._subs.clear()
        self.writer.close()
