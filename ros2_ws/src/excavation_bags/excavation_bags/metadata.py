"""A bag's ``metadata.yaml`` (rosbag2 format version 9) and the QoS profiles it lists.

rosbag2 (ROS 2 Jazzy) describes a bag directory in ``metadata.yaml``: the storage
(``mcap``), the time span, every topic with its type, RIHS01 type hash, serialization
format and offered QoS profiles (version 9: a YAML list of mappings), the files, and a
free ``custom_data`` mapping. The same QoS list, as YAML text, is each MCAP channel's
``offered_qos_profiles`` metadata, so a player can offer latched topics (transient local)
again. Pure module: no ``rclpy``; QoS profiles are ``rosbags.interfaces.Qos`` values.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
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

from excavation_bags.errors import BagFormatError
from excavation_common.files import write_text_atomic
from excavation_common.loaders import load_yaml

PRODUCER = "ant-bag"
"""``custom_data.producer`` of bags this project records."""

FORMAT = "ant-bag/1"
"""``custom_data.format``: what the topics of a project bag mean (docs/bags.md)."""

ROS_DISTRO = "jazzy"
VERSION = 9
"""The rosbag2 metadata version written (ROS 2 Jazzy's)."""

METADATA_FILE = "metadata.yaml"

_INFINITE_NS = 2**63 - 1


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

    def time(t: QosTime) -> dict:
        return {"sec": int(t.sec), "nsec": int(t.nsec)}

    return [
        {
            "history": q.history.name.lower(),
            "depth": int(q.depth),
            "reliability": q.reliability.name.lower(),
            "durability": q.durability.name.lower(),
            "deadline": time(q.deadline),
            "lifespan": time(q.lifespan),
            "liveliness": q.liveliness.name.lower(),
            "liveliness_lease_duration": time(q.liveliness_lease_duration),
            "avoid_ros_namespace_conventions": bool(q.avoid_ros_namespace_conventions),
        }
        for q in profiles
    ]


def qos_yaml(profiles: Sequence[Qos]) -> str:
    """QoS profiles as YAML text (an MCAP channel's ``offered_qos_profiles``)."""
    return yaml.safe_dump(qos_dicts(profiles), default_flow_style=False, sort_keys=False).strip()


def _enum(kind, value):
    if isinstance(value, int) and not isinstance(value, bool):
        return kind(value)
    return kind.__members__[str(value).upper()]


def _time(value) -> QosTime:
    return QosTime(int(value["sec"]), int(value["nsec"]))


def parse_qos(value) -> list[Qos]:
    """QoS profiles from metadata.yaml's list or a channel's YAML text; ``[]`` when unreadable.

    Names (``transient_local``) and the numbers older writers use are both accepted.
    """
    try:
        items = yaml.safe_load(value) if isinstance(value, str) else value
        if not isinstance(items, list):
            return []
        return [
            Qos(
                _enum(QosHistory, item["history"]),
                int(item["depth"]),
                _enum(QosReliability, item["reliability"]),
                _enum(QosDurability, item["durability"]),
                _time(item["deadline"]),
                _time(item["lifespan"]),
                _enum(QosLiveliness, item["liveliness"]),
                _time(item["liveliness_lease_duration"]),
                bool(item.get("avoid_ros_namespace_conventions", False)),
            )
            for item in items
        ]
    except (yaml.YAMLError, KeyError, TypeError, ValueError, AttributeError):
        return []


def latched(profiles: Sequence[Qos]) -> bool:
    """True when every offered profile is transient local (a latched topic)."""
    return bool(profiles) and all(p.durability == QosDurability.TRANSIENT_LOCAL for p in profiles)


# --- metadata.yaml ----------------------------------------------------------------------------


@dataclass(frozen=True)
class TopicRecord:
    """One ``topics_with_message_count`` entry of metadata.yaml.

    Attributes:
        name: Topic name.
        msgtype: ROS type.
        qos: Offered QoS profiles.
        type_hash: RIHS01 hash of the type.
        count: Messages written.
    """

    name: str
    msgtype: str
    qos: tuple[Qos, ...]
    type_hash: str
    count: int


def bag_metadata(
    file_name: str,
    topics: Sequence[TopicRecord],
    start_ns: int | None,
    end_ns: int,
    custom_data: dict[str, str],
) -> dict:
    """``metadata.yaml`` content (version 9, one MCAP file, no rosbag2 compression)."""
    start = start_ns or 0
    duration = max(0, end_ns - start) if start_ns is not None else 0
    count = sum(t.count for t in topics)
    return {
        "rosbag2_bagfile_information": {
            "version": VERSION,
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
                        "type_description_hash": t.type_hash,
                    },
                    "message_count": t.count,
                }
                for t in topics
            ],
            "compression_format": "",
            "compression_mode": "",
            "relative_file_paths": [file_name],
            "files": [
                {
                    "path": file_name,
                    "starting_time": {"nanoseconds_since_epoch": start},
                    "duration": {"nanoseconds": duration},
                    "message_count": count,
                }
            ],
            "custom_data": dict(custom_data),
            "ros_distro": ROS_DISTRO,
        }
    }


def metadata_text(metadata: dict) -> str:
    """metadata.yaml text of :func:`bag_metadata` content."""
    return yaml.safe_dump(metadata, default_flow_style=False, sort_keys=False)


def write_metadata(bag_dir: Path, metadata: dict) -> None:
    """Write ``bag_dir/metadata.yaml`` atomically (readers see the old or the new one)."""
    write_text_atomic(Path(bag_dir) / METADATA_FILE, metadata_text(metadata))


def read_metadata(bag_dir: Path) -> dict | None:
    """``rosbag2_bagfile_information`` of ``bag_dir/metadata.yaml``; ``None`` when absent.

    Raises:
        BagFormatError: The file exists but is not rosbag2 metadata.
    """
    meta = Path(bag_dir) / METADATA_FILE
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


def metadata_qos(info: dict | None) -> dict[str, list[Qos]]:
    """Topic -> offered QoS profiles listed in metadata (skips malformed entries)."""
    out: dict[str, list[Qos]] = {}
    for entry in (info or {}).get("topics_with_message_count") or []:
        try:
            tm = entry["topic_metadata"]
            profiles = parse_qos(tm.get("offered_qos_profiles"))
        except (KeyError, TypeError, AttributeError):
            continue
        if profiles:
            out[tm["name"]] = profiles
    return out
