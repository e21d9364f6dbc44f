"""Reading a bag directory (or one MCAP file), complete or cut short by a crash.

A complete MCAP file is read through its summary and index with the ``mcap`` library's
public reader (``mcap.reader.make_reader``); the QoS profiles come from ``metadata.yaml``
(or from the MCAP channels when it is missing). A file without its summary or footer (a
recorder killed mid-recording) is read record by record with ``mcap.stream_reader``
instead, up to the last complete chunk; :attr:`Bag.truncated` and :attr:`Bag.warnings`
say so. Message bytes are the CDR buffers ROS middleware produces (what an rclpy
subscription with ``raw=True`` receives and what ``Publisher.publish(bytes)`` sends).
Pure module: no ``rclpy``.
"""

from __future__ import annotations

import os
import struct
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.records import Channel, Footer, Message, Schema
from mcap.stream_reader import StreamReader

from excavation_bags.errors import BagFormatError, BagNotFoundError, UnknownTypeError
from excavation_bags.metadata import PRODUCER, VERSION, metadata_qos, parse_qos, read_metadata
from excavation_bags.topics import TopicInfo, ensure_type, known_type, typestore

_MAGIC = b"\x89MCAP0\r\n"
_READ_ERRORS = (McapError, struct.error, EOFError, OSError, ValueError)


@dataclass
class Bag:
    """A bag opened for reading (see :func:`open_bag`).

    Attributes:
        path: The bag directory (or the MCAP file given).
        mcap: The MCAP file read.
        topics: Topic name -> :class:`~excavation_bags.topics.TopicInfo`.
        custom_data: ``custom_data`` of ``metadata.yaml`` (empty when unknown).
        ros_distro: ``ros_distro`` of ``metadata.yaml`` (``None`` when unknown).
        start_ns: Timestamp of the first message (0 when there is none).
        end_ns: Timestamp of the last message (0 when there is none).
        truncated: Why the MCAP file is incomplete, or ``None`` for a complete file.
        warnings: Things a user should know (truncation, unknown producer, unknown types).
    """

    path: Path
    mcap: Path
    topics: dict[str, TopicInfo]
    custom_data: dict[str, str]
    ros_distro: str | None
    start_ns: int = 0
    end_ns: int = 0
    truncated: str | None = None
    warnings: list[str] = field(default_factory=list)
    _scanned: list[tuple[str, int, bytes]] | None = field(default=None, repr=False)

    @property
    def producer(self) -> str | None:
        """Who recorded the bag (``custom_data.producer``)."""
        return self.custom_data.get("producer")

    @property
    def message_count(self) -> int:
        """Messages in the bag (as read back)."""
        return sum(t.count for t in self.topics.values())

    @property
    def duration_s(self) -> float:
        """Seconds from the first message to the last."""
        return max(0, self.end_ns - self.start_ns) / 1e9

    @property
    def size_bytes(self) -> int:
        """Size of the MCAP file."""
        return self.mcap.stat().st_size

    @property
    def bytes_per_minute(self) -> float | None:
        """File size per minute of recording (``None`` for a bag shorter than 1 ms)."""
        duration = self.duration_s
        return self.size_bytes / duration * 60.0 if duration >= 1e-3 else None

    def messages(self, topics: Iterable[str] | None = None) -> Iterator[tuple[str, int, bytes]]:
        """``(topic, timestamp_ns, cdr_bytes)`` in timestamp order, optionally for some topics.

        Raises:
            BagFormatError: The file cannot be read (it changed since it was opened).
        """
        wanted = set(self.topics if topics is None else topics) & set(self.topics)
        if self._scanned is not None:
            for item in self._scanned:
                if item[0] in wanted:
                    yield item
            return
        try:
            with self.mcap.open("rb") as f:
                reader = make_reader(f)
                for _, channel, message in reader.iter_messages(
                    topics=sorted(wanted), log_time_order=True
                ):
                    yield channel.topic, message.log_time, bytes(message.data)
        except _READ_ERRORS as exc:
            raise BagFormatError(self.mcap, "messages", None, f"unreadable: {exc}") from None

    def decode(self, topic: str, raw: bytes):
        """Deserialise a message of ``topic`` (rosbags message object, same fields as rclpy).

        Raises:
            UnknownTypeError: The type is neither a common_interfaces type nor defined in
                the bag.
            BagFormatError: The bytes do not decode as that type.
        """
        info = self.topics[topic]
        if not ensure_type(info):
            raise UnknownTypeError(
                self.path, f"topics[{info.name}].type", info.msgtype, "no definition to decode it"
            )
        try:
            return typestore().deserialize_cdr(raw, info.msgtype)
        except Exception as exc:  # rosbags raises plain errors on bad CDR
            raise BagFormatError(
                self.mcap, f"topics[{topic}]", info.msgtype, f"message does not decode: {exc}"
            ) from None


def topic_sizes(bag: Bag) -> dict[str, int]:
    """Message payload bytes per topic (reads every message once)."""
    sizes = dict.fromkeys(bag.topics, 0)
    for topic, _ts, raw in bag.messages():
        sizes[topic] += len(raw)
    return sizes


def find_mcap(path: Path) -> Path:
    """The one MCAP file of a bag directory (or ``path`` itself when it is one).

    Raises:
        BagNotFoundError: No such directory, or no ``.mcap`` in it.
        BagFormatError: Several ``.mcap`` files (a split bag), or not an ``.mcap`` file.
    """
    if path.is_file():
        if path.suffix != ".mcap":
            raise BagFormatError(path, "path", path.name, "expected a bag directory or .mcap file")
        return path
    if not path.is_dir():
        raise BagNotFoundError(path, "path", str(path), "no such bag directory")
    files = sorted(path.glob("*.mcap"))
    if not files:
        raise BagNotFoundError(path, "files", [], "the directory holds no .mcap file")
    if len(files) > 1:
        raise BagFormatError(
            path, "files", [f.name for f in files], "split bags (several files) are not supported"
        )
    return files[0]


def _schema_fields(schema: Schema | None) -> tuple[str, str]:
    if schema is None:
        return "", ""
    return schema.name, schema.data.decode("utf-8", "replace")


def _read_indexed(mcap: Path, meta: dict | None) -> tuple[dict[str, TopicInfo], int, int] | None:
    """Topics and time span of a complete MCAP file from its summary; None without one."""
    try:
        with mcap.open("rb") as f:
            f.seek(-8, os.SEEK_END)
            if f.read(8) != _MAGIC:
                return None
            f.seek(0)
            summary = make_reader(f).get_summary()
    except _READ_ERRORS:
        return None
    if summary is None or summary.statistics is None:
        return None
    meta_qos = metadata_qos(meta)
    counts = summary.statistics.channel_message_counts
    topics: dict[str, TopicInfo] = {}
    for channel in summary.channels.values():
        msgtype, msgdef = _schema_fields(summary.schemas.get(channel.schema_id))
        qos = meta_qos.get(channel.topic) or parse_qos(
            channel.metadata.get("offered_qos_profiles", "")
        )
        info = topics.setdefault(channel.topic, TopicInfo(channel.topic, msgtype, 0, qos, msgdef))
        info.count += counts.get(channel.id, 0)
    stats = summary.statistics
    if stats.message_count == 0:
        return topics, 0, 0
    return topics, stats.message_start_time, stats.message_end_time


def _scan_mcap(mcap: Path) -> tuple[dict[str, TopicInfo], list[tuple[str, int, bytes]], str | None]:
    """Read an MCAP file record by record, as far as it is complete.

    Returns topics, messages (sorted by time) and why the file is incomplete (or None).
    """
    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    topics: dict[str, TopicInfo] = {}
    messages: list[tuple[str, int, bytes]] = []
    complete = False
    problem = None
    with mcap.open("rb") as f:
        try:
            for record in StreamReader(f, emit_chunks=False).records:
                if isinstance(record, Schema):
                    schemas[record.id] = record
                elif isinstance(record, Channel):
                    channels[record.id] = record
                    msgtype, msgdef = _schema_fields(schemas.get(record.schema_id))
                    qos = parse_qos(record.metadata.get("offered_qos_profiles", ""))
                    topics.setdefault(
                        record.topic, TopicInfo(record.topic, msgtype, 0, qos, msgdef)
                    )
                elif isinstance(record, Message):
                    ch = channels.get(record.channel_id)
                    if ch is None:
                        continue
                    messages.append((ch.topic, record.log_time, bytes(record.data)))
                    topics[ch.topic].count += 1
                elif isinstance(record, Footer):
                    complete = True
        except (struct.error, EOFError):
            problem = "the file is cut short"
        except (McapError, ValueError, OSError) as exc:
            problem = f"{type(exc).__name__}: {exc}" if str(exc) else "the file is cut short"
    if problem or not complete:
        last = f"; last message at {messages[-1][1] / 1e9:.3f} s" if messages else ""
        where = "ends without its MCAP footer" if not complete else "ends inside its footer"
        problem = (
            f"{mcap.name} {where} ({problem or 'the file is cut short'}): "
            f"read {len(messages)} messages from its complete chunks{last}"
        )
    messages.sort(key=lambda m: m[1])
    return topics, messages, problem


def open_bag(path: str | Path) -> Bag:
    """Open a bag directory (or an MCAP file) for reading.

    Raises:
        BagNotFoundError: No bag there.
        BagFormatError: Unreadable metadata, or not an MCAP file at all.
    """
    p = Path(path)
    mcap = find_mcap(p)
    bag_dir = p if p.is_dir() else p.parent
    meta = read_metadata(bag_dir) if p.is_dir() else None
    with mcap.open("rb") as f:
        head = f.read(8)
    if head != _MAGIC:
        raise BagFormatError(mcap, "magic", head[:8], "not an MCAP file")
    custom = dict((meta or {}).get("custom_data") or {})
    distro = (meta or {}).get("ros_distro")
    warnings: list[str] = []
    if p.is_dir() and meta is None:
        warnings.append(f"{bag_dir}: no metadata.yaml; topics are read from {mcap.name}")
    if meta is not None and meta.get("version") != VERSION:
        warnings.append(
            f"{bag_dir / 'metadata.yaml'}: version = {meta.get('version')!r}: "
            f"written for version {VERSION}; reading anyway"
        )
    indexed = _read_indexed(mcap, meta)
    if indexed is not None:
        topics, start, end = indexed
        bag = Bag(bag_dir, mcap, topics, custom, distro, start, end)
    else:
        topics, scanned, problem = _scan_mcap(mcap)
        start, end = (scanned[0][1], scanned[-1][1]) if scanned else (0, 0)
        bag = Bag(bag_dir, mcap, topics, custom, distro, start, end, problem, _scanned=scanned)
        if problem:
            warnings.append(f"{bag_dir}: truncated: {problem}; `ant-bag recover` writes a copy")
    if bag.producer != PRODUCER:
        warnings.append(
            f"{bag_dir}: custom_data.producer = {bag.producer!r}: not recorded by {PRODUCER}; "
            "topics are read by name and type as the node suite defines them"
        )
    for t in bag.topics.values():
        if not known_type(t.msgtype) and not t.msgdef:
            warnings.append(f"{bag_dir}: topic {t.name}: unknown type {t.msgtype!r}; skipped")
    bag.warnings = warnings
    return bag
