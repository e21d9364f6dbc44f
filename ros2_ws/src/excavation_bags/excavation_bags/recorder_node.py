"""The bag recorder as a ROS node (``ant-bag record``; composable on a trial's executor).

The node looks for matching topics on the graph every ``discovery_period`` seconds and
subscribes to each new one with a QoS that fits its publishers, the way ``ros2 bag record``
does: transient local when every publisher offers it (so latched maps published before the
recorder started are still recorded), reliable when every publisher is reliable. Messages
are stored as the CDR bytes the middleware delivers (``raw=True``), stamped with the time
the publisher sent them (the DDS source timestamp): the bag keeps the publishers' order even
when the recorder runs late. Each topic's offered QoS profiles go into the bag.

**Camera frames are recorded compressed.** A raw ``sensor_msgs/Image`` topic matching
``compress_topics`` (default ``*/image_raw``) is stored as ``<topic>/compressed``
(``sensor_msgs/CompressedImage``, ``image_codec`` ``jpeg`` or lossless ``png``; see
:mod:`excavation_bags.images`), the name and format ``image_transport`` gives it, so a bag
of a camera that publishes compressed frames itself looks the same. When the camera
already publishes ``<topic>/compressed`` (and it is selected), that topic is recorded as it
comes and the raw one is left out; should the camera's compressed topic appear only after
the recorder began compressing the raw one, it is the one left out (one source per bag
topic; :attr:`RecorderNode.skipped` says which). ``image_codec: none`` records raw frames
as they are.

Every ``flush_period`` seconds the writer ends its MCAP chunk and rewrites
``metadata.yaml`` (see :mod:`excavation_bags.writer`), so a crash loses at most that
much. :meth:`RecorderNode.close` finishes the bag; call it before destroying the node.
The parameters are :class:`RecorderParams` (``config/bag_recorder.yaml``).
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from sensor_msgs.msg import CompressedImage, Image

from excavation_bags.errors import BagError, UnknownTypeError
from excavation_bags.images import (
    COMPRESSED_TYPE,
    IMAGE_TYPE,
    compress,
    compressed_topic,
)
from excavation_bags.metadata import qos_from_profile
from excavation_bags.topics import SUITE_TOPICS, known_type, topic_selected
from excavation_bags.writer import BagWriter
from excavation_common.params import ParameterError, param
from excavation_common.ros import RECORDER_NODE, declare_params, diagnostics


@dataclass(frozen=True)
class RecorderParams:
    """Parameters of the bag recorder (mirrored in ``config/bag_recorder.yaml``)."""

    out: str = param("", "bag directory to create (required; must not exist)")
    topics: tuple[str, ...] = param(
        ("",), 'names or globs to record; [""] = every suite topic (docs/bags.md)'
    )
    flush_period: float = param(
        0.5,
        "s between chunk flushes and metadata.yaml rewrites (the crash loss bound)",
        low=0.01,
        high=60.0,
    )
    discovery_period: float = param(0.1, "s between looks for new topics", low=0.01, high=60.0)
    depth: int = param(100, "queue depth of each subscription", low=1, high=100_000)
    height_unit: float = param(
        0.05, "m per soil unit, stored in the bag for the report", low=1e-4, high=10.0
    )
    image_codec: str = param(
        "jpeg",
        "how raw camera frames are stored: jpeg, png (lossless) or none (raw)",
        choices=("jpeg", "png", "none"),
    )
    compress_topics: tuple[str, ...] = param(
        ("*/image_raw",), "raw sensor_msgs/Image topics (names or globs) stored compressed"
    )
    jpeg_quality: int = param(90, "JPEG quality (1..100)", low=1, high=100, read_only=False)
    png_level: int = param(
        1, "PNG compression level (0 fastest .. 9 smallest)", low=0, high=9, read_only=False
    )


def message_class(msgtype: str):
    """The rclpy message class of ``pkg/msg/Name``, or ``None`` when it is not installed."""
    try:
        pkg, kind, name = msgtype.split("/")
        return getattr(importlib.import_module(f"{pkg}.{kind}"), name)
    except (ValueError, ImportError, AttributeError):
        return None


def subscription_qos(profiles, depth: int) -> QoSProfile:
    """The QoS ``ros2 bag record`` uses for publishers offering ``profiles``."""
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
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


class RecorderNode(Node):
    """Records matching topics into a bag directory.

    Raises:
        ParameterError: A parameter is out of range, or ``out`` is empty.
        BagExistsError: ``out`` exists.
    """

    def __init__(self, custom_data: dict[str, str] | None = None, **kwargs) -> None:
        super().__init__(kwargs.pop("node_name", RECORDER_NODE), **kwargs)
        self.params = declare_params(self, RecorderParams, on_change=self._on_params)
        if not self.params.out:
            raise ParameterError(
                self.get_fully_qualified_name(), "out", "", "required: the bag directory to create"
            )
        self.patterns = [t for t in self.params.topics if t] or list(SUITE_TOPICS)
        self.compress_patterns = [t for t in self.params.compress_topics if t]
        extra = {"height_unit": repr(self.params.height_unit), **(custom_data or {})}
        self.writer = BagWriter(self.params.out, extra)
        self.skipped: dict[str, str] = {}
        self.received = 0
        self.frames = {"compressed": 0, "bad": 0, "raw_bytes": 0, "stored_bytes": 0}
        self.frame_error = ""
        self._subs = {}
        self._sources: dict[str, str] = {}  # bag topic -> graph topic it is recorded from
        self.diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.discover()
        self.create_timer(self.params.discovery_period, self.discover)
        self.create_timer(self.params.flush_period, self.flush)
        self.create_timer(1.0, self.publish_diagnostics)

    @property
    def depth(self) -> int:
        """Queue depth of each subscription."""
        return self.params.depth

    def _on_params(self, params: RecorderParams) -> None:
        self.params = params  # only jpeg_quality and png_level can change at runtime

    def publish_diagnostics(self) -> None:
        """OK while recording; WARN naming the topics it cannot record."""
        if self.writer.closed:
            return
        skipped = "; ".join(f"{t}: {why}" for t, why in self.skipped.items())
        level = DiagnosticStatus.WARN if skipped or self.frame_error else DiagnosticStatus.OK
        message = f"recording {len(self._subs)} topics" + (
            f"; not recorded: {skipped}" if skipped else ""
        )
        if self.frame_error:
            message += f"; {self.frames['bad']} frames not recorded, last: {self.frame_error}"
        values = {
            "messages": self.received,
            "topics": len(self._subs),
            "skipped": len(self.skipped),
            "bytes": self.writer.bytes_written,
            "frames_compressed": self.frames["compressed"],
        }
        if self.frames["stored_bytes"]:
            values["frame_ratio"] = f"{self.frames['raw_bytes'] / self.frames['stored_bytes']:.1f}"
        self.diag_pub.publish(diagnostics(self, level, message, values))

    def _compresses(self, topic: str, msgtype: str) -> bool:
        return (
            msgtype == IMAGE_TYPE
            and self.params.image_codec != "none"
            and topic_selected(topic, self.compress_patterns)
        )

    def discover(self) -> None:
        """Subscribe to matching topics that appeared since the last look."""
        if self.writer.closed:
            return
        graph = self.get_topic_names_and_types()
        published = {name for name, types in graph if COMPRESSED_TYPE in types}
        for topic, types in graph:
            if topic in self._subs or topic in self.skipped:
                continue
            if not topic_selected(topic, self.patterns):
                continue
            msgtype = types[0]
            cls = message_class(msgtype)
            if cls is None or not known_type(msgtype):
                self.skipped[topic] = f"unknown type {msgtype}"
                self.get_logger().warning(f"not recording {topic}: unknown type {msgtype}")
                continue
            compressing = self._compresses(topic, msgtype)
            bag_topic = compressed_topic(topic) if compressing else topic
            camera = compressing and bag_topic in published
            if (camera and topic_selected(bag_topic, self.patterns)) or bag_topic in self._sources:
                # one source per bag topic: the camera's own compressed frames come first
                source = self._sources.get(bag_topic, bag_topic)
                self.skipped[topic] = (
                    f"the recorder stores {source} as {bag_topic}"
                    if source != bag_topic
                    else f"the camera publishes {bag_topic}, which is recorded instead"
                )
                continue
            infos = self.get_publishers_info_by_topic(topic)
            offered = [qos_from_profile(i.qos_profile) for i in infos]
            if not offered:
                continue  # the publisher left again; look next time
            try:
                self.writer.add_topic(
                    bag_topic, COMPRESSED_TYPE if compressing else msgtype, offered
                )
            except UnknownTypeError as exc:
                self.skipped[topic] = str(exc)
                continue
            self._sources[bag_topic] = topic
            qos = subscription_qos([i.qos_profile for i in infos], self.params.depth)
            if compressing:
                self.writer.custom_data[f"compressed:{topic}"] = (
                    f"stored as {bag_topic} ({self.params.image_codec})"
                )
                self._subs[topic] = self.create_subscription(
                    Image, topic, lambda m, info, t=topic: self.on_raw_image(t, m, info), qos
                )
            else:
                self._subs[topic] = self.create_subscription(
                    cls,
                    topic,
                    lambda raw, info, t=topic: self.on_message(t, raw, info),
                    qos,
                    raw=True,
                )

    def _stamp(self, info: dict) -> int:
        return int(info.get("source_timestamp") or 0) or self.get_clock().now().nanoseconds

    def on_message(self, topic: str, raw: bytes, info: dict) -> None:
        """Store one message, stamped with its source (publish) time."""
        if self.writer.closed:
            return
        self.writer.write(topic, self._stamp(info), raw)
        self.received += 1

    def on_raw_image(self, topic: str, msg: Image, info: dict) -> None:
        """Store one raw camera frame as ``<topic>/compressed``."""
        if self.writer.closed:
            return
        p = self.params
        try:
            out = compress(
                msg, CompressedImage(), p.image_codec, p.jpeg_quality, p.png_level, topic
            )
        except (BagError, ValueError) as exc:
            self.frames["bad"] += 1
            self.frame_error = f"{topic}: {exc}"
            return
        data = serialize_message(out)
        self.writer.write(compressed_topic(topic), self._stamp(info), data)
        self.received += 1
        self.frames["compressed"] += 1
        self.frames["raw_bytes"] += len(msg.data)
        self.frames["stored_bytes"] += len(out.data)

    def flush(self) -> None:
        """Make what was received so far survive a crash."""
        if not self.writer.closed:
            self.writer.flush()

    @property
    def recorded(self) -> dict[str, int]:
        """Messages recorded per bag topic."""
        return {t.name: t.count for t in self.writer.topics.values()}

    def close(self) -> None:
        """Finish the bag (MCAP summary and final metadata.yaml)."""
        for sub in self._subs.values():
            self.destroy_subscription(sub)
        self._subs.clear()
        self.writer.close()
