"""Retakes: the synthetic camera renders the last instant again when the localizer asks.

A lockstep trial renders one frame per tick; a robot that one frame's glare hides would hold
the whole team for a tick timeout. The localizer (``retakes``) asks on ``/overhead/retake``
for another frame of the same stamp (tests/test_localizer_node.py); here the sensors node
answers it, with new noise, and ignores a request for any other stamp.
"""

from __future__ import annotations

import numpy as np
from builtin_interfaces.msg import Time as TimeMsg
from excavation_interfaces.msg import Retake
from geometry_msgs.msg import PoseWithCovarianceStamped
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import Image

from excavation_common.messages import grid_to_image, pose_message
from excavation_common.ros import LATCHED
from overhead_localizer.params import RETAKE_TOPIC

ROWS = COLS = 16
CELL = 0.25


def test_sensors_answer_a_retake_of_the_last_frame_only(ros):
    from excavation_sim.sensors_node import SensorsNode

    sensors = ros.add(
        SensorsNode(
            context=ros.context,
            parameter_overrides=[Parameter("robots", value=1), Parameter("reliable", value=True)],
        )
    )
    node = ros.add(Node("probe", context=ros.context))
    pose_pub = node.create_publisher(PoseWithCovarianceStamped, "/truth/robot_0/pose", 10)
    map_pub = node.create_publisher(Image, "/truth/worksite/height_map", LATCHED)
    retake_pub = node.create_publisher(Retake, RETAKE_TOPIC, 10)
    frames: list[Image] = []
    node.create_subscription(Image, "/overhead/image_raw", frames.append, 10)
    stamp = TimeMsg(sec=3)
    map_pub.publish(grid_to_image(np.zeros((ROWS, COLS)), "32FC1", stamp=stamp))
    assert ros.spin_until(lambda: pose_pub.get_subscription_count() > 0)
    assert ros.spin_until(lambda: retake_pub.get_subscription_count() > 0)
    assert ros.spin_until(lambda: sensors.heights is not None)
    pose_pub.publish(pose_message(5, 5, 0, CELL, 1e-4, 1e-3, stamp=stamp))
    assert ros.spin_until(lambda: len(frames) == 1)

    # Two requests from one writer arrive in order, and any frame the first gave would go out
    # before the second's: once the second's frame is in, the first was refused.
    retake_pub.publish(Retake(stamp=TimeMsg(sec=2)))  # not the last frame's stamp
    retake_pub.publish(Retake(stamp=stamp, unseen=[0]))
    assert ros.spin_until(lambda: len(frames) >= 2 and sensors.retakes >= 1)
    assert len(frames) == 2
    first, again = (np.frombuffer(bytes(f.data), np.uint8) for f in frames)
    assert frames[1].header.stamp == stamp and sensors.retakes == 1
    assert first.shape == again.shape and not np.array_equal(first, again)  # its own noise
    assert np.abs(first.astype(int) - again.astype(int)).mean() < 10  # of the same scene
