"""Writing a bag directory: ``metadata.yaml`` and one MCAP file with profile ``ros2``.

The MCAP file is written with the ``mcap`` library's public :class:`mcap.writer.Writer`
on a file object this module owns: ``ros2msg`` schemas from the ROS 2 Jazzy type store,
CDR payloads, each channel's offered QoS profiles in its metadata, and at the end a
``rosbag2`` metadata record holding the ``metadata.yaml`` text (as rosbag2's MCAP plugin
writes it). The layout is the one ``ros2 bag info`` / ``ros2 bag play`` of a full ROS 2
install expect (not tried here: this environment has no ``ros2 bag``); the ``rosbags``
reader and the ``mcap`` reader read these bags (tested).

Crash safety: :class:`BagWriter` writes ``metadata.yaml`` as soon as the bag opens and again
at every :meth:`BagWriter.flush`, which first ends the MCAP chunk in progress
(``Writer.flush``) and syncs the file to disk. A recorder killed mid-recording (even
``kill -9``) leaves an MCAP file without its summary and footer, whose complete chunks
:func:`excavation_bags.reader.open_bag` reads back and
:func:`excavation_bags.recover.recover_bag` copies into a complete bag. At most the
messages since the last flush are lost. Pure module: no ``rclpy``.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from importlib.metadata import version
from pathlib import Path

from mcap.writer import CompressionType, Writer
from rosbags.interfaces import Qos

from excavation_bags.errors import BagExistsError, UnknownTypeError
from excavation_bags.metadata import (
    FORMAT,
    PRODUCER,
    TopicRecord,
    bag_metadata,
    metadata_text,
    qos_yaml,
    write_metadata,
)
from excavation_bags.topics import known_type, message_definition, type_hash

CHUNK_SIZE = 1 << 20
"""Bytes of messages after which a chunk is ended without waiting for a flush."""


@dataclass
class _Topic:
    name: str
    msgtype: str
    qos: tuple[Qos, ...]
    digest: str
    channel_id: int
    count: int = 0
    size: int = 0


class BagWriter:
    """Writes one bag directory; use as a context manager or call :meth:`close`.

    Args:
        path: Bag directory to create (must not exist).
        custom_data: Extra ``custom_data`` entries (strings) for ``metadata.yaml``;
            ``producer`` and ``format`` are always set. :attr:`custom_data` may be
            extended while recording; each metadata rewrite carries the entries so far.

    Raises:
        BagExistsError: ``path`` exists.
    """

    def __init__(self, path: str | Path, custom_data: dict[str, str] | None = None) -> None:
        self.path = Path(path)
        if self.path.exists():
            raise BagExistsError(
                self.path, "path", str(self.path), "exists; bags are not overwritten"
            )
        self.path.mkdir(parents=True)
        self.mcap_path = self.path / f"{self.path.name}.mcap"
        self._file = self.mcap_path.open("xb")
        self._mcap = Writer(self._file, chunk_size=CHUNK_SIZE, compression=CompressionType.NONE)
        self._mcap.start(profile="ros2", library=f"{PRODUCER} (mcap {version('mcap')})")
        self._schemas: dict[str, int] = {}
        self.custom_data = {"producer": PRODUCER, "format": FORMAT}
        self.custom_data.update({k: str(v) for k, v in (custom_data or {}).items()})
        self.topics: dict[str, _Topic] = {}
        self.start_ns: int | None = None
        self.end_ns = 0
        self.closed = False
        self.write_metadata()

    def add_topic(self, topic: str, msgtype: str, qos: Sequence[Qos] = ()) -> None:
        """Declare a topic before writing to it (a second call for a topic does nothing).

        Raises:
            UnknownTypeError: ``msgtype`` is not a ROS 2 Jazzy common_interfaces type.
        """
        if topic in self.topics:
            return
        if not known_type(msgtype):
            raise UnknownTypeError(self.path, f"topics[{topic}].type", msgtype, "unknown type")
        schema_id = self._schemas.get(msgtype)
        if schema_id is None:
            encoding, text = message_definition(msgtype)
            schema_id = self._mcap.register_schema(msgtype, encoding, text.encode("utf-8"))
            self._schemas[msgtype] = schema_id
        channel_id = self._mcap.register_channel(
            topic, "cdr", schema_id, {"offered_qos_profiles": qos_yaml(qos)}
        )
        self.topics[topic] = _Topic(topic, msgtype, tuple(qos), type_hash(msgtype), channel_id)

    def write(self, topic: str, timestamp_ns: int, data: bytes) -> None:
        """Append one CDR-serialised message (``timestamp_ns``: nanoseconds since the epoch)."""
        t = self.topics[topic]
        ts = int(timestamp_ns)
        self._mcap.add_message(t.channel_id, log_time=ts, data=bytes(data), publish_time=ts)
        t.count += 1
        t.size += len(data)
        self.start_ns = ts if self.start_ns is None else min(self.start_ns, ts)
        self.end_ns = max(self.end_ns, ts)

    def flush(self) -> None:
        """End the chunk in progress, sync the MCAP file and rewrite ``metadata.yaml``."""
        if self.closed:
            return
        self._mcap.flush()
        os.fsync(self._file.fileno())
        self.write_metadata()

    def close(self) -> None:
        """Finish the MCAP file (summary, footer) and write the final ``metadata.yaml``."""
        if self.closed:
            return
        self._mcap.flush()  # the last chunk before the summary's metadata record
        self._mcap.add_metadata("rosbag2", {"serialized_metadata": metadata_text(self.metadata())})
        self._mcap.finish()
        self._file.close()
        self.closed = True
        self.write_metadata()

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    @property
    def bytes_written(self) -> int:
        """Message payload bytes written so far (all topics)."""
        return sum(t.size for t in self.topics.values())

    def metadata(self) -> dict:
        """``metadata.yaml`` content for what has been written so far."""
        records = [
            TopicRecord(t.name, t.msgtype, t.qos, t.digest, t.count) for t in self.topics.values()
        ]
        return bag_metadata(
            self.mcap_path.name, records, self.start_ns, self.end_ns, self.custom_data
        )

    def write_metadata(self) -> None:
        """Write ``metadata.yaml`` atomically (readers see the old or the new one)."""
        write_metadata(self.path, self.metadata())
