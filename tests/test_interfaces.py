"""The workspace's interface packages, generated and compiled into the venv by make setup
(tools/build_interfaces.py): the wheels' CMake exports fixed, tf2_msgs' TFMessage on the wire
as a full ROS 2 Jazzy install has it."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location(
    "build_interfaces", ROOT / "tools/build_interfaces.py"
)
build_interfaces = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(build_interfaces)

MANYLINUX = (
    "set_target_properties(x PROPERTIES\n"
    '  INTERFACE_INCLUDE_DIRECTORIES "${_IMPORT_PREFIX}/include/x;'
    "/opt/python/cp311-cp311/include/python3.11;"
    '/opt/python/cp311-cp311/lib/python3.11/site-packages/numpy/_core/include"\n)\n'
)


def test_the_fix_up_points_the_exports_at_this_pythons_headers_and_is_idempotent():
    fixed = build_interfaces.rewrite_includes(MANYLINUX, "/venv/py/include", "/venv/np/include")
    assert '"${_IMPORT_PREFIX}/include/x;/venv/py/include;/venv/np/include"' in fixed
    assert build_interfaces.rewrite_includes(fixed, "/venv/py/include", "/venv/np/include") == fixed
    untouched = 'INTERFACE_INCLUDE_DIRECTORIES "${_IMPORT_PREFIX}/include/y"\n'
    assert build_interfaces.rewrite_includes(untouched, "/a", "/b") == untouched


def test_no_export_of_the_venv_names_a_missing_python_or_numpy_include():
    missing = []
    for path in sorted(Path(sys.prefix, "share").glob("*/cmake/*Export.cmake")):
        for m in build_interfaces._INCLUDES.finditer(path.read_text()):
            for d in m.group(2).split(";"):
                if build_interfaces._PYTHON_OR_NUMPY.match(d) and not Path(d).is_dir():
                    missing.append(f"{path.name}: {d}")
    assert not missing, missing[:5]


def test_the_interface_packages_are_found_by_their_build_type():
    assert build_interfaces.interface_packages() == ["excavation_interfaces", "tf2_msgs"]


def test_tf_messages_serialise_as_ros2_jazzys_tf2_msgs():
    """rclpy's bytes of a TFMessage read back with rosbags' Jazzy type store (the upstream
    definition), and rosbags' bytes read back in rclpy as the same message."""
    from geometry_msgs.msg import TransformStamped
    from rclpy.serialization import deserialize_message, serialize_message
    from rosbags.typesys import Stores, get_typestore
    from tf2_msgs.msg import TFMessage

    t = TransformStamped()
    t.header.frame_id, t.child_frame_id = "map", "robot_0/base_link"
    t.header.stamp.sec, t.header.stamp.nanosec = 12, 345
    t.transform.translation.x, t.transform.rotation.z, t.transform.rotation.w = 1.5, 0.6, 0.8
    ours = serialize_message(TFMessage(transforms=[t, TransformStamped()]))
    store = get_typestore(Stores.ROS2_JAZZY)
    theirs = store.deserialize_cdr(ours, "tf2_msgs/msg/TFMessage")
    assert [x.child_frame_id for x in theirs.transforms] == ["robot_0/base_link", ""]
    assert theirs.transforms[0].transform.translation.x == 1.5
    # rosbags' bytes (its alignment padding zeroed, Fast CDR's left as found) read back in rclpy
    message = TFMessage(transforms=[t, TransformStamped()])
    again = bytes(store.serialize_cdr(theirs, "tf2_msgs/msg/TFMessage"))
    assert len(again) == len(ours) and deserialize_message(again, TFMessage) == message


def test_a_tf_message_goes_through_rclpy(ros):
    from geometry_msgs.msg import TransformStamped
    from rclpy.node import Node
    from rclpy.qos import QoSDurabilityPolicy, QoSProfile
    from tf2_msgs.msg import TFMessage

    node = ros.add(Node("tf_probe", context=ros.context))
    latched = QoSProfile(depth=1, durability=QoSDurabilityPolicy.TRANSIENT_LOCAL)
    got = []
    node.create_subscription(TFMessage, "/tf_static", got.append, latched)
    pub = node.create_publisher(TFMessage, "/tf_static", latched)
    msg = TFMessage(transforms=[TransformStamped(child_frame_id="overhead_camera")])
    pub.publish(msg)
    assert ros.spin_until(lambda: got, timeout=10)
    assert got[0].transforms[0].child_frame_id == "overhead_camera"


def test_drive_messages_serialise_as_the_bag_layer_defines_them():
    """rclpy's bytes of a DriveStatus read back with the bag layer's type store (taught the
    suite's types from the installed ``.msg`` files), whose RIHS01 hash is rosidl's own."""
    import json
    import sys
    from pathlib import Path

    from excavation_interfaces.msg import DriveGoal, DriveStatus
    from rclpy.serialization import deserialize_message, serialize_message

    from excavation_bags.topics import type_hash, typestore

    goal = DriveGoal(tick=2**40 + 3, word=0xABC, turn=DriveGoal.TURN_LEFT, robot=7)
    goal.stamp.sec, goal.stamp.nanosec = 12, 500
    ours = serialize_message(DriveStatus(goal=goal, status=DriveStatus.STATUS_ABORTED))
    theirs = typestore().deserialize_cdr(ours, "excavation_interfaces/msg/DriveStatus")
    assert (theirs.goal.tick, theirs.goal.word, theirs.goal.turn, theirs.goal.robot) == (
        2**40 + 3, 0xABC, -1, 7,
    )  # fmt: skip
    assert (theirs.goal.stamp.sec, theirs.goal.stamp.nanosec, theirs.status) == (12, 500, 6)
    again = bytes(typestore().serialize_cdr(theirs, "excavation_interfaces/msg/DriveStatus"))
    assert deserialize_message(again, DriveStatus) == deserialize_message(ours, DriveStatus)
    for name in ("DriveGoal", "DriveStatus"):
        generated = json.loads(
            (Path(sys.prefix) / "share/excavation_interfaces/msg" / f"{name}.json").read_text()
        )
        rosidl = {h["type_name"]: h["hash_string"] for h in generated["type_hashes"]}
        msgtype = f"excavation_interfaces/msg/{name}"
        assert type_hash(msgtype) == rosidl[msgtype]
