"""``sensor_msgs/Image`` <-> BGR arrays for camera frames (no ``rclpy``; messages duck-typed)."""

from __future__ import annotations

import numpy as np

from overhead_localizer.errors import ImageError


def frame_from_message(msg, topic: str = "/overhead/image_raw") -> np.ndarray:
    """The ``uint8 [height, width, 3]`` BGR array of a ``bgr8`` image message.

    Raises:
        ImageError: Another encoding, a wrong step or data size (topic, field, value).
    """
    if msg.encoding != "bgr8":
        raise ImageError(topic, "encoding", msg.encoding, "expected bgr8")
    if msg.step != msg.width * 3:
        raise ImageError(topic, "step", msg.step, f"expected width x 3 = {msg.width * 3}")
    if len(msg.data) != msg.height * msg.step:
        raise ImageError(
            topic,
            "data",
            f"{len(msg.data)} bytes",
            f"expected height x step = {msg.height * msg.step}",
        )
    return np.frombuffer(bytes(msg.data), dtype=np.uint8).reshape(msg.height, msg.width, 3)


def frame_to_message(image: np.ndarray, msg, frame_id: str = "overhead_camera", stamp=None):
    """Fill ``msg`` (a fresh ``sensor_msgs/Image``) with a BGR frame and return it."""
    arr = np.ascontiguousarray(image, dtype=np.uint8)
    if stamp is not None:
        msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.height, msg.width = arr.shape[:2]
    msg.encoding = "bgr8"
    msg.is_bigendian = 0
    msg.step = arr.shape[1] * 3
    msg.data = arr.tobytes()
    return msg
