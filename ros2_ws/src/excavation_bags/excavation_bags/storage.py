"""Writing and reading ROS 2 bags (rosbag2 directory, MCAP storage) without rosbag2.

A bag is a directory holding ``metadata.yaml`` (rosbag2 format version 9, the way ROS 2
Jazzy writes it) and one MCAP file with profile ``ros2``: message definitions as
``ros2msg`` schemas, CDR payloads, and each topic's offered QoS profiles in the channel
metadata and in ``metadata.yaml``, so a player can offer latched topics (transient local)
again. The layout is the one ``ros2 bag info`` / ``ros2 bag play`` of a full ROS 2 install
expect (not tried here: this environment has no ``ros2 bag``); the ``rosbags`` reader and
the ``mcap`` library read these bags (tested).

Crash safety: :class:`BagWriter` writes ``metadata.yaml`` as soon as the bag opens and again
at every :meth:`BagWriter.flush`, which also closes the MCAP chunk in progress and syncs the
file. A recorder killed mid-recording (even ``kill -9``) leaves an MCAP file without its
summary and footer: :func:`open_bag` then reads it record by record up to the last
complete chunk, says so in :attr:`Bag.warnings`, and :func:`recover_bag` writes a complete
copy that every tool reads. At most the messages since the last flush are lost.

This module is pure (no ``rclpy``): the recorder and player nodes, the report and the tests
share it. Message bytes are the CDR buffers ROS middleware produces (what an rclpy
subscription with ``raw=True`` receives and what ``Publisher.publish(bytes)`` sends).
"""

from __future__ import annotations

import fnmatch
import os
import struct
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import yaml
from rosbags.interfaces import (
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)
from rosbags.rosbag2 import ReaderError, StoragePlugin, Writer, WriterError
from rosbags.rosbag2.metadata import dump_qos_v9, parse_qos
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from excavation_bags.errors import (
    BagError,
    BagExistsError,
    BagFormatError,
    BagNotFoundError,
    UnknownTypeError,
)
from excavation_common.files import write_text_atomic
from excavation_common.loaders import load_yaml

PRODUCER = "ant-bag"
"""``custom_data.producer`` of bags this project records."""

FORMAT = "ant-bag/1"
"""``custom_data.format``: what the topics of a project bag mean (docs/bags.md)."""

ROS_DISTRO = "jazzy"

SUITE_TOPICS: tuple[str, ...] = (
    "/clock",
    "/overhead/image_raw",
    "/worksite/scan",
    "/worksite/height_map",
    "/worksite/map_info",
    "/worksite/fitness",
    "/worksite/markers",
    "/blueprint/goal",
    "/blueprint/zones",
    "/robot_*/pose",
    "/robot_*/behaviour",
    "/robot_*/stuck",
    "/robot_*/imu",
    "/robot_*/blade/joint_states",
    "/robot_*/blade/commands",
    "/robot_*/blade/servo_command",
    "/robot_*/blade/servo_state",
    "/diagnostics",
)
"""The node suite's topics (DESIGN.md, docs/interfaces.md); ``*`` matches a robot index."""

_TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
_MAGIC = b"\x89MCAP0\r\n"
_INFINITE_NS = 2**63 - 1


def typestore():
    """The rosbags type store with ROS 2 Jazzy's message definitions (common_interfaces)."""
    return _TYPESTORE


def topic_selected(topic: str, patterns: Sequence[str]) -> bool:
    """True when ``topic`` matches one of ``patterns`` (names or ``fnmatch`` globs)."""
    return any(fnmatch.fnmatchcase(topic, p) for p in patterns)


# --- QoS --------------------------------------------------------------------------------------


def _qos_time(ns: int) -> QosTime:
    sec, nsec = divmod(min(int(ns), _INFINITE_NS), 10**9)
    return QosTime(sec, nsec)


def qos_from_profile(profile) -> Qos:
    """A rosbags ``Qos`` from an rclpy ``QoSProfile`` (read by attribute; no rclpy import).

    Durations are written as rosbag2 writes them (infinite = 9223372036 s 854775807 ns).
    """

    def ns(duration) -> int:
        return int(getattr(duration, "nanoseconds", duration))

    return Qos(
        QosHistory(int(profile.history)),
        int(profile.depth),
        QosReliability(int(profile.reliability)),
        QosDurability(int(profile.durability)),
        _qos_time(ns(profile.deadline)),
        _qos_time(ns(profile.lifespan)),
        QosLiveliness(int(profile.liveliness)),
        _qos_time(ns(profile.liveliness_lease_duration)),
        bool(profile.avoid_ros_namespace_conventions),
    )


def qos_dicts(profiles: Sequence[Qos]) -> list[dict]:
    """QoS profiles as ``metadata.yaml`` (version 9) lists them."""
    return [dict(d) for d in dump_qos_v9(list(profiles))]


def latched(profiles: Sequence[Qos]) -> bool:
    """True when every offered profile is transient local (a latched topic)."""
    return bool(profiles) and all(p.durability == QosDurability.TRANSIENT_LOCAL for p in profiles)


# --- writing ----------------------------------------------------------------------------------


@dataclass
class _Topic:
    name: str
    msgtype: str
    qos: list[Qos]
    digest: str
    connection: object
    count: int = 0


class BagWriter:
    """Writes one bag directory; use as a context manager or call :meth:`close`.

    Args:
        path: Bag directory to create (must not exist).
        custom_data: Extra ``custom_data`` entries (strings) for ``metadata.yaml``;
            ``producer`` and ``format`` are always set.

    Raises:
        BagExistsError: ``path`` exists.
    """

    def __init__(self, path: str | Path, custom_data: dict[str, str] | None = None) -> None:
        self.path = Path(path)
        if self.path.exists():
            raise BagExistsError(
                self.path, "path", str(self.path), "exists; bags are not overwritten"
            )
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._writer = Writer(self.path, version=9, storage_plugin=StoragePlugin.MCAP)
        self._writer.open()
        self.custom_data = {"producer": PRODUCER, "format": FORMAT, **(custom_data or {})}
        for key, value in self.custom_data.items():
            self._writer.set_custom_data(key, str(value))
        self.topics: dict[str, _Topic] = {}
        self.start_ns: int | None = None
        self.end_ns = 0
        self.closed = False
        self.write_metadata()

    @property
    def mcap_path(self) -> Path:
        """The MCAP file inside the bag directory."""
        return (
            self._writer.storage.path
            if self._writer.storage
            else self.path / (f"{self.path.name}.mcap")
        )

    def add_topic(self, topic: str, msgtype: str, qos: Sequence[Qos] = ()) -> None:
        """Declare a topic before writing to it.

        Raises:
            UnknownTypeError: ``msgtype`` is not a ROS 2 Jazzy common_interfaces type.
        """
        if topic in self.topics:
            return
        if msgtype not in _TYPESTORE.types:
            raise UnknownTypeError(self.path, f"topics[{topic}].type", msgtype, "unknown type")
        connection = self._writer.add_connection(
            topic, msgtype, typestore=_TYPESTORE, offered_qos_profiles=list(qos)
        )
        self.topics[topic] = _Topic(
            topic, msgtype, list(qos), _TYPESTORE.hash_rihs01(msgtype), connection
        )

    def write(self, topic: str, timestamp_ns: int, data: bytes) -> None:
        """Append one CDR-serialised message (``timestamp_ns``: nanoseconds since the epoch)."""
        t = self.topics[topic]
        self._writer.write(t.connection, int(timestamp_ns), data)
        t.count += 1
        self.start_ns = timestamp_ns if self.start_ns is None else min(self.start_ns, timestamp_ns)
        self.end_ns = max(self.end_ns, timestamp_ns)

    def flush(self) -> None:
        """Close the chunk in progress, sync the MCAP file and rewrite ``metadata.yaml``."""
        storage = self._writer.storage
        if storage is None:
            return
        if storage.chunk.bio.tell():
            storage.close_chunk()
        storage.bio.flush()
        os.fsync(storage.bio.fileno())
        self.write_metadata()

    def close(self) -> None:
        """Finish the MCAP file (summary, footer) and write the final ``metadata.yaml``."""
        if self.closed:
            return
        self._writer.close()
        self.closed = True
        self.write_metadata()

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def metadata(self) -> dict:
        """``metadata.yaml`` content for what has been written so far."""
        start = self.start_ns or 0
        duration = max(0, self.end_ns - start) if self.start_ns is not None else 0
        count = sum(t.count for t in self.topics.values())
        name = f"{self.path.name}.mcap"
        return {
            "rosbag2_bagfile_information": {
                "version": 9,
                "storage_identifier": "mcap",
                "duration": {"nanoseconds": duration},
                "starting_time": {"nanoseconds_since_epoch": start},
                "message_count": count,
                "topics_with_message_count": [
                    {
                        "topic_metadata": {
                            "name": t.name,
                            "type": t.msgtype,
                            "serialization_format": "cdr",
                            "offered_qos_profiles": qos_dicts(t.qos),
                            "type_description_hash": t.digest,
                        },
                        "message_count": t.count,
                    }
                    for t in self.topics.values()
                ],
                "compression_format": "",
                "compression_mode": "",
                "relative_file_paths": [name],
                "files": [
                    {
                        "path": name,
                        "starting_time": {"nanoseconds_since_epoch": start},
                        "duration": {"nanoseconds": duration},
                        "message_count": count,
                    }
                ],
                "custom_data": dict(self.custom_data),
                "ros_distro": ROS_DISTRO,
            }
        }

    def write_metadata(self) -> None:
        """Write ``metadata.yaml`` atomically (readers see the old or the new one)."""
        text = yaml.safe_dump(self.metadata(), default_flow_style=False, sort_keys=False)
        write_text_atomic(self.path / "metadata.yaml", text)


# --- reading ----------------------------------------------------------------------------------


@dataclass
class TopicInfo:
    """One topic of a bag.

    Attributes:
        name: Topic name.
        msgtype: ROS type (``sensor_msgs/msg/Image``).
        count: Messages read back (or listed in the metadata).
        qos: Offered QoS profiles.
        msgdef: Message definition stored in the bag (``ros2msg`` text), if any.
    """

    name: str
    msgtype: str
    count: int
    qos: list[Qos] = field(default_factory=list)
    msgdef: str = ""


@dataclass
class Bag:
    """A bag opened for reading (see :func:`open_bag`).

    Attributes:
        path: The bag directory (or the MCAP file given).
        mcap: The MCAP file read.
        topics: Topic name -> :class:`TopicInfo`.
        custom_data: ``custom_data`` of ``metadata.yaml`` (empty when unknown).
        ros_distro: ``ros_distro`` of ``metadata.yaml`` (``None`` when unknown).
        truncated: Why the MCAP file is incomplete, or ``None`` for a complete file.
        warnings: Things a user should know (truncation, unknown producer, unknown types).
    """

    path: Path
    mcap: Path
    topics: dict[str, TopicInfo]
    custom_data: dict[str, str]
    ros_distro: str | None
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

    def messages(self, topics: Iterable[str] | None = None) -> Iterator[tuple[str, int, bytes]]:
        """``(topic, timestamp_ns, cdr_bytes)`` in timestamp order, optionally for some topics."""
        wanted = set(self.topics if topics is None else topics) & set(self.topics)
        if self._scanned is not None:
            for item in self._scanned:
                if item[0] in wanted:
                    yield item
            return
        from mcap.exceptions import McapError
        from mcap.reader import make_reader

        try:
            with self.mcap.open("rb") as f:
                reader = make_reader(f)
                for _, channel, message in reader.iter_messages(
                    topics=sorted(wanted), log_time_order=True
                ):
                    yield channel.topic, message.log_time, bytes(message.data)
        except (McapError, struct.error, EOFError, OSError, ValueError) as exc:
            raise BagFormatError(self.mcap, "messages", None, f"unreadable: {exc}") from None

    def decode(self, topic: str, raw: bytes):
        """Deserialise a message of ``topic`` (rosbags message object, same fields as rclpy).

        Raises:
            UnknownTypeError: The type is neither a common_interfaces type nor defined in
                the bag.
            BagFormatError: The bytes do not decode as that type.
        """
        info = self.topics[topic]
        _ensure_type(self, info)
        try:
            return _TYPESTORE.deserialize_cdr(raw, info.msgtype)
        except Exception as exc:  # rosbags raises plain errors on bad CDR
            raise BagFormatError(
                self.mcap, f"topics[{topic}]", info.msgtype, f"message does not decode: {exc}"
            ) from None


def _ensure_type(bag: Bag, info: TopicInfo) -> None:
    if info.msgtype in _TYPESTORE.types:
        return
    if info.msgdef:
        try:
            _TYPESTORE.register(get_types_from_msg(info.msgdef, info.msgtype))
            return
        except Exception:  # noqa: BLE001, S110 - any parse failure means: unknown type
            pass
    raise UnknownTypeError(
        bag.path, f"topics[{info.name}].type", info.msgtype, "no definition to decode it"
    )


def _find_mcap(path: Path) -> Path:
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


def _read_metadata(path: Path) -> dict | None:
    meta = path / "metadata.yaml"
    if not meta.is_file():
        return None
    try:
        # Bounded (4 MiB), no duplicate keys or aliases: see excavation_common.loaders.
        data = load_yaml(meta, BagFormatError, max_bytes=4 << 20)
        info = data["rosbag2_bagfile_information"]
        if not isinstance(info, dict):
            raise TypeError("not a mapping")
        return info
    except (yaml.YAMLError, KeyError, TypeError, OSError, UnicodeDecodeError) as exc:
        raise BagFormatError(
            meta, "rosbag2_bagfile_information", None, f"unreadable metadata: {exc}"
        ) from None


def _qos_list(value) -> list[Qos]:
    """QoS profiles from metadata.yaml's list or an MCAP channel's YAML string ([] if bad)."""
    try:
        items = yaml.safe_load(value) if isinstance(value, str) else value
        return parse_qos(items) if isinstance(items, list) else []
    except (yaml.YAMLError, ReaderError, KeyError, TypeError, ValueError, AttributeError):
        return []


def _read_indexed(mcap: Path, meta: dict | None) -> dict[str, TopicInfo] | None:
    """Topics of a complete MCAP file from its summary, or None when it has none."""
    from mcap.exceptions import McapError
    from mcap.reader import make_reader

    try:
        with mcap.open("rb") as f:
            f.seek(-8, os.SEEK_END)
            if f.read(8) != _MAGIC:
                return None
            f.seek(0)
            summary = make_reader(f).get_summary()
    except (McapError, struct.error, EOFError, OSError, ValueError):
        return None
    if summary is None or summary.statistics is None:
        return None
    meta_qos = {}
    for entry in (meta or {}).get("topics_with_message_count") or []:
        try:
            tm = entry["topic_metadata"]
            meta_qos[tm["name"]] = tm.get("offered_qos_profiles")
        except (KeyError, TypeError):
            continue
    counts = summary.statistics.channel_message_counts
    topics: dict[str, TopicInfo] = {}
    for channel in summary.channels.values():
        schema = summary.schemas.get(channel.schema_id)
        info = topics.setdefault(
            channel.topic,
            TopicInfo(
                channel.topic,
                schema.name if schema else "",
                0,
                _qos_list(
                    meta_qos.get(channel.topic) or channel.metadata.get("offered_qos_profiles", "")
                ),
                schema.data.decode("utf-8", "replace") if schema else "",
            ),
        )
        info.count += counts.get(channel.id, 0)
    return topics


def _scan_mcap(mcap: Path) -> tuple[dict[str, TopicInfo], list[tuple[str, int, bytes]], str | None]:
    """Read an MCAP file record by record, as far as it is complete.

    Returns topics, messages (sorted by time) and why the file is incomplete (or None).
    """
    from mcap.exceptions import McapError
    from mcap.records import Channel, Footer, Message, Schema
    from mcap.stream_reader import StreamReader

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
                    schema = schemas.get(record.schema_id)
                    qos = _qos_list(record.metadata.get("offered_qos_profiles", ""))
                    topics.setdefault(
                        record.topic,
                        TopicInfo(
                            record.topic,
                            schema.name if schema else "",
                            0,
                            qos,
                            schema.data.decode("utf-8", "replace") if schema else "",
                        ),
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

    A complete MCAP file is read through its summary and index (the ``mcap`` library); the
    QoS profiles come from ``metadata.yaml`` (or from the MCAP channels when it is
    missing). A file that lacks its summary or footer (a recorder that crashed) is read
    record by record instead; :attr:`Bag.truncated` and :attr:`Bag.warnings` say so.

    Raises:
        BagNotFoundError: No bag there.
        BagFormatError: Unreadable metadata, or not an MCAP file at all.
    """
    p = Path(path)
    mcap = _find_mcap(p)
    bag_dir = p if p.is_dir() else p.parent
    meta = _read_metadata(bag_dir) if p.is_dir() else None
    with mcap.open("rb") as f:
        head = f.read(8)
    if head != _MAGIC:
        raise BagFormatError(mcap, "magic", head[:8], "not an MCAP file")
    custom = dict((meta or {}).get("custom_data") or {})
    distro = (meta or {}).get("ros_distro")
    warnings: list[str] = []
    if p.is_dir() and meta is None:
        warnings.append(f"{bag_dir}: no metadata.yaml; topics are read from {mcap.name}")
    if meta is not None and meta.get("version") != 9:
        warnings.append(
            f"{bag_dir / 'metadata.yaml'}: version = {meta.get('version')!r}: "
            "written for version 9; reading anyway"
        )
    topics = _read_indexed(mcap, meta)
    if topics is not None:
        bag = Bag(bag_dir, mcap, topics, custom, distro)
    else:
        topics, scanned, problem = _scan_mcap(mcap)
        bag = Bag(bag_dir, mcap, topics, custom, distro, problem, _scanned=scanned)
        if problem:
            warnings.append(f"{bag_dir}: truncated: {problem}; `ant-bag recover` writes a copy")
    if bag.producer != PRODUCER:
        warnings.append(
            f"{bag_dir}: custom_data.producer = {bag.producer!r}: not recorded by {PRODUCER}; "
            "topics are read by name and type as the node suite defines them"
        )
    for t in bag.topics.values():
        if t.msgtype not in _TYPESTORE.types and not t.msgdef:
            warnings.append(f"{bag_dir}: topic {t.name}: unknown type {t.msgtype!r}; skipped")
    bag.warnings = warnings
    return bag


def recover_bag(path: str | Path, out: str | Path) -> Bag:
    """Write everything readable from ``path`` into a new, complete bag at ``out``.

    The input is never modified. Returns the new bag, opened.

    Raises:
        BagError: The input cannot be read or ``out`` exists.
    """
    bag = open_bag(path)
    custom = {k: str(v) for k, v in bag.custom_data.items() if k not in ("producer", "format")}
    if bag.truncated:
        custom["recovered_from"] = f"{bag.mcap.name}: {bag.truncated}"
    try:
        with BagWriter(out, custom) as writer:
            if bag.producer != PRODUCER:
                writer.custom_data["producer"] = str(bag.producer or "unknown")
            for t in bag.topics.values():
                if t.msgtype in _TYPESTORE.types:
                    writer.add_topic(t.name, t.msgtype, t.qos)
            for topic, ts, raw in bag.messages():
                if topic in writer.topics:
                    writer.write(topic, ts, raw)
    except WriterError as exc:
        raise BagError(out, "path", str(out), str(exc)) from None
    return open_bag(out)
