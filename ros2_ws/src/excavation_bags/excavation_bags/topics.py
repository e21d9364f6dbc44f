"""What a bag's topics are: the suite's topic names, message types and their definitions.

Message definitions come from ROS 2 Jazzy's common_interfaces as the ``rosbags`` type store
holds them (:func:`typestore`), and from the suite's own interface packages
(``excavation_interfaces``, ``tf2_msgs``: their ``.msg`` files as ``make setup`` installs
them, :data:`PROJECT_INTERFACES`); only those types are recorded, each with its definition,
so any reader decodes them without the packages. A bag from elsewhere may carry other types
with their definitions, which :func:`ensure_type` registers for decoding. Pure module: no
``rclpy``.
"""

from __future__ import annotations

import fnmatch
import os
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from rosbags.interfaces import Qos
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

SUITE_TOPICS: tuple[str, ...] = (
    "/clock",
    "/overhead/image_raw",
    "/overhead/image_raw/compressed",
    "/overhead/camera_info",
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
    "/robot_*/blade/plant_state",
    "/robot_*/blade/tick_state",
    "/robot_*/cmd_vel",
    "/robot_*/drive/status",
    "/robot_*/drive/throttle",
    "/robot_*/drive/override",
    "/robot_*/drive/operator",
    "/robot_*/enabled",
    "/team/*",
    "/tick/*",
    "/diagnostics",
    "/tf",
    "/tf_static",
)
"""The node suite's topics (docs/interfaces.md); ``*`` matches a robot index
(``/team/*``: e-stop, heartbeat, tick, snapshot requests and their acknowledgements;
``/tick/*``: the snapshot the team tick republishes per tick in a continuous trial;
``/robot_*/blade/tick_state``: in the dome, the blade state it republishes per tick).

``/overhead/image_raw`` is recorded as ``/overhead/image_raw/compressed`` (see
:mod:`excavation_bags.recorder_node`)."""

_TYPESTORE = get_typestore(Stores.ROS2_JAZZY)

PROJECT_INTERFACES = ("excavation_interfaces",)
"""The suite's interface packages whose types the type store learns from their ``.msg``
files (``tf2_msgs``' TFMessage is in the Jazzy store already)."""


def _interface_dirs(package: str) -> list[Path]:
    """Where ``package``'s ``.msg`` files are installed: this prefix, then the ament path."""
    prefixes = [sys.prefix, *os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep)]
    return [Path(p, "share", package, "msg") for p in prefixes if p]


def _register_project_types() -> None:
    """Teach the type store the suite's own messages (nested ones first: in one call)."""
    for package in PROJECT_INTERFACES:
        folder = next((d for d in _interface_dirs(package) if d.is_dir()), None)
        if folder is None:
            continue  # not built (make setup builds it): its topics are not recorded
        types = {}
        for msg in sorted(folder.glob("*.msg")):
            types.update(get_types_from_msg(msg.read_text(), f"{package}/msg/{msg.stem}"))
        _TYPESTORE.register(types)


_register_project_types()


def typestore():
    """The rosbags type store with ROS 2 Jazzy's message definitions (common_interfaces)."""
    return _TYPESTORE


def known_type(msgtype: str) -> bool:
    """True when ``msgtype`` (``pkg/msg/Name``) has a definition in the type store."""
    return msgtype in _TYPESTORE.types


def message_definition(msgtype: str) -> tuple[str, str]:
    """``(schema encoding, definition text)`` of a known type, as rosbag2 stores it in MCAP.

    The text is the ``ros2msg`` form: the type's fields, then each nested type after a
    line of ``=`` (what ``ros2 bag record`` writes as the channel's schema).
    """
    text, _ = _TYPESTORE.generate_msgdef(msgtype, ros_version=2)
    encoding = "ros2idl" if text.startswith("=" * 80 + "\nIDL: ") else "ros2msg"
    return encoding, text


def type_hash(msgtype: str) -> str:
    """The type's RIHS01 hash (``type_description_hash`` in metadata.yaml)."""
    return _TYPESTORE.hash_rihs01(msgtype)


def topic_selected(topic: str, patterns: Sequence[str]) -> bool:
    """True when ``topic`` matches one of ``patterns`` (names or ``fnmatch`` globs)."""
    return any(fnmatch.fnmatchcase(topic, p) for p in patterns)


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


def ensure_type(info: TopicInfo) -> bool:
    """Make ``info.msgtype`` decodable: known, or registered from the bag's definition.

    Returns:
        False when the type is unknown and the bag has no definition that parses.
    """
    if known_type(info.msgtype):
        return True
    if info.msgdef:
        try:
            _TYPESTORE.register(get_types_from_msg(info.msgdef, info.msgtype))
            return True
        except Exception:  # noqa: BLE001 - any parse failure means: unknown type
            return False
    return False
