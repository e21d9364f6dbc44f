"""Camera frames as messages <-> BGR arrays (no ``rclpy``; messages duck-typed).

:func:`frame_from_message` decodes a ``sensor_msgs/Image`` in any of the encodings a
camera driver commonly sends (``bgr8``, ``rgb8``, ``bgra8``, ``rgba8``, ``mono8``, the four
8-bit Bayer mosaics, demosaiced as ``cv_bridge`` does, and packed YUV 4:2:2, converted as
``cv_bridge`` does with OpenCV's BT.601 conversion); :func:`frame_from_compressed` decodes a
``sensor_msgs/CompressedImage`` (``jpeg`` or ``png``, as ``image_transport``'s compressed
plugin sends it: ``format`` such as ``"bgr8; jpeg compressed bgr8"``). Both give the
``uint8 [height, width, 3]`` BGR array the localizer works on. A ``mono8`` frame carries
no colour, so its LEDs cannot be told apart: it decodes, and :data:`COLOURLESS` names it
so the node can report it.
"""

from __future__ import annotations

import cv2
import numpy as np

from overhead_localizer.errors import ImageError

_BAYER = {  # ROS encoding -> OpenCV code (OpenCV names the pattern from the second row)
    "bayer_rggb8": cv2.COLOR_BayerBG2BGR,
    "bayer_bggr8": cv2.COLOR_BayerRG2BGR,
    "bayer_gbrg8": cv2.COLOR_BayerGR2BGR,
    "bayer_grbg8": cv2.COLOR_BayerGB2BGR,
}
_YUV422 = {  # ROS encoding -> OpenCV code (sensor_msgs/image_encodings.hpp names both orders)
    "yuv422": cv2.COLOR_YUV2BGR_UYVY,  # U Y0 V Y1 (deprecated name of uyvy)
    "uyvy": cv2.COLOR_YUV2BGR_UYVY,
    "yuv422_yuy2": cv2.COLOR_YUV2BGR_YUY2,  # Y0 U Y1 V (deprecated name of yuyv; usb_cam's yuyv)
    "yuyv": cv2.COLOR_YUV2BGR_YUY2,
}
_CONVERT = {  # ROS encoding -> OpenCV code to BGR; bgr8 is used as it is
    "rgb8": cv2.COLOR_RGB2BGR,
    "bgra8": cv2.COLOR_BGRA2BGR,
    "rgba8": cv2.COLOR_RGBA2BGR,
    "mono8": cv2.COLOR_GRAY2BGR,
    **_BAYER,
    **_YUV422,
}
_CHANNELS = {  # bytes per pixel (a YUV 4:2:2 pair of pixels shares its U and V)
    "bgr8": 3,
    "rgb8": 3,
    "bgra8": 4,
    "rgba8": 4,
    "mono8": 1,
    **{name: 1 for name in _BAYER},
    **{name: 2 for name in _YUV422},
}

ENCODINGS = tuple(_CHANNELS)
"""Encodings :func:`frame_from_message` decodes."""

COLOURLESS = ("mono8",)
"""Encodings whose frames cannot show the LEDs' colours."""

FORMATS = ("jpeg", "png")
"""Compressed formats :func:`frame_from_compressed` decodes."""


def frame_from_message(msg, topic: str = "/overhead/image_raw") -> np.ndarray:
    """The ``uint8 [height, width, 3]`` BGR array of an image message.

    Raises:
        ImageError: An unsupported encoding, a wrong step or data size (topic, field, value).
    """
    channels = _CHANNELS.get(msg.encoding)
    if channels is None:
        raise ImageError(topic, "encoding", msg.encoding, f"expected one of {', '.join(ENCODINGS)}")
    if msg.encoding in _YUV422 and msg.width % 2:
        raise ImageError(topic, "width", msg.width, f"{msg.encoding} needs an even width")
    if msg.step != msg.width * channels:
        raise ImageError(
            topic, "step", msg.step, f"expected width x {channels} = {msg.width * channels}"
        )
    if len(msg.data) != msg.height * msg.step:
        raise ImageError(
            topic,
            "data",
            f"{len(msg.data)} bytes",
            f"expected height x step = {msg.height * msg.step}",
        )
    raw = np.frombuffer(bytes(msg.data), dtype=np.uint8)
    image = raw.reshape(msg.height, msg.width, channels)
    if msg.encoding == "bgr8":
        return image
    if channels == 1:
        image = image[:, :, 0]
    return cv2.cvtColor(image, _CONVERT[msg.encoding])


def frame_from_compressed(msg, topic: str = "/overhead/image_raw/compressed") -> np.ndarray:
    """The ``uint8 [height, width, 3]`` BGR array of a ``CompressedImage`` (jpeg or png).

    Raises:
        ImageError: Another format, or data that does not decode.
    """
    fmt = str(msg.format).lower()
    if not any(name in fmt for name in FORMATS):
        raise ImageError(topic, "format", msg.format, "expected jpeg or png")
    data = np.frombuffer(bytes(msg.data), dtype=np.uint8)
    image = cv2.imdecode(data, cv2.IMREAD_COLOR) if data.size else None
    if image is None:
        raise ImageError(topic, "data", f"{data.size} bytes", f"do not decode as {msg.format}")
    if "rgb8" in fmt.split(";")[0]:  # compressed from rgb8: channels were written swapped
        image = np.ascontiguousarray(image[:, :, ::-1])
    return image


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


def frame_to_compressed(
    image: np.ndarray,
    msg,
    fmt: str = "jpeg",
    quality: int = 90,
    frame_id: str = "overhead_camera",
    stamp=None,
):
    """Fill ``msg`` (a fresh ``sensor_msgs/CompressedImage``) with a BGR frame and return it.

    ``format`` is written as ``image_transport`` does (``"bgr8; jpeg compressed bgr8"``).

    Raises:
        ValueError: ``fmt`` is neither jpeg nor png.
    """
    if fmt not in FORMATS:
        raise ValueError(f"format {fmt!r}: expected jpeg or png")
    params = [cv2.IMWRITE_JPEG_QUALITY, int(quality)] if fmt == "jpeg" else []
    ok, buf = cv2.imencode(".jpg" if fmt == "jpeg" else ".png", np.ascontiguousarray(image), params)
    if not ok:
        raise ValueError(f"the frame does not encode as {fmt}")
    if stamp is not None:
        msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.format = f"bgr8; {fmt} compressed bgr8"
    msg.data = buf.tobytes()
    return msg
