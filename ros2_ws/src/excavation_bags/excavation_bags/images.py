"""Camera frames in bags: raw ``sensor_msgs/Image`` <-> ``sensor_msgs/CompressedImage``.

A raw 1280 x 720 ``bgr8`` frame is 2.76 MB, about 83 MB/s at 30 fps; the recorder stores
camera frames as ``CompressedImage`` instead (JPEG, or PNG when every pixel must survive),
the way ROS camera drivers publish ``image_raw/compressed`` through ``image_transport``:
``format`` is ``"<encoding>; jpeg compressed bgr8"`` (or ``png``), the header is the raw
frame's. The player, the report and the trial-data reader decode them back to arrays with
OpenCV. Messages are duck-typed (rclpy or rosbags objects with the same fields); pure
module: no ``rclpy``.
"""

from __future__ import annotations

import cv2
import numpy as np

from excavation_bags.errors import BagError

COMPRESSED_SUFFIX = "/compressed"
"""``image_transport``'s name of the compressed topic beside a raw image topic."""

IMAGE_TYPE = "sensor_msgs/msg/Image"
COMPRESSED_TYPE = "sensor_msgs/msg/CompressedImage"
CODECS = ("jpeg", "png")

_CHANNELS = {"bgr8": 3, "rgb8": 3, "mono8": 1, "bgra8": 4, "rgba8": 4}


class ImageDataError(BagError):
    """A camera frame's fields do not describe its data, or the data does not decode."""


def compressed_topic(raw_topic: str) -> str:
    """``/overhead/image_raw`` -> ``/overhead/image_raw/compressed``."""
    return raw_topic.rstrip("/") + COMPRESSED_SUFFIX


def raw_topic(compressed: str) -> str | None:
    """The raw topic a ``.../compressed`` topic stands for, or ``None``."""
    if compressed.endswith(COMPRESSED_SUFFIX) and len(compressed) > len(COMPRESSED_SUFFIX):
        return compressed[: -len(COMPRESSED_SUFFIX)]
    return None


def raw_array(msg, topic: str = "image") -> np.ndarray:
    """The pixels of a raw image message: ``uint8 [h, w, 3]`` BGR, or ``[h, w]`` for mono8.

    Raises:
        ImageDataError: An encoding other than bgr8 / rgb8 / mono8 / bgra8 / rgba8, or a
            step or data size that does not match (naming topic, field and value).
    """
    channels = _CHANNELS.get(msg.encoding)
    if channels is None:
        raise ImageDataError(topic, "encoding", msg.encoding, f"expected one of {list(_CHANNELS)}")
    height, width, step = int(msg.height), int(msg.width), int(msg.step)
    if step < width * channels:
        raise ImageDataError(topic, "step", step, f"expected >= width x {channels}")
    data = np.frombuffer(bytes(msg.data), dtype=np.uint8)
    if data.size != height * step:
        raise ImageDataError(
            topic, "data", f"{data.size} bytes", f"expected height x step = {height * step}"
        )
    rows = data.reshape(height, step)[:, : width * channels]
    image = rows.reshape(height, width, channels) if channels > 1 else rows.reshape(height, width)
    if msg.encoding == "rgb8":
        return np.ascontiguousarray(image[..., ::-1])
    if channels == 4:
        code = cv2.COLOR_BGRA2BGR if msg.encoding == "bgra8" else cv2.COLOR_RGBA2BGR
        return cv2.cvtColor(image, code)
    return np.ascontiguousarray(image)


def encode(image: np.ndarray, codec: str, jpeg_quality: int = 90, png_level: int = 1) -> bytes:
    """JPEG or PNG bytes of a BGR (or mono) array.

    Raises:
        ValueError: An unknown codec, or OpenCV refuses the image.
    """
    if codec == "jpeg":
        ok, buf = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, int(jpeg_quality)])
    elif codec == "png":
        ok, buf = cv2.imencode(".png", image, [cv2.IMWRITE_PNG_COMPRESSION, int(png_level)])
    else:
        raise ValueError(f"codec {codec!r}: expected one of {CODECS}")
    if not ok:
        raise ValueError(f"OpenCV could not encode a {image.shape} image as {codec}")
    return buf.tobytes()


def compress(msg, out, codec: str, jpeg_quality: int = 90, png_level: int = 1, topic="image"):
    """Fill ``out`` (a fresh ``CompressedImage``) from the raw image ``msg``; return it.

    ``format`` follows ``compressed_image_transport``: ``"bgr8; jpeg compressed bgr8"``
    (mono8 frames stay single-channel: ``"mono8; png compressed mono8"``).

    Raises:
        ImageDataError: ``msg`` does not hold the image it describes.
    """
    image = raw_array(msg, topic)
    target = "mono8" if image.ndim == 2 else "bgr8"
    out.header = msg.header
    out.format = f"{msg.encoding}; {codec} compressed {target}"
    out.data = encode(image, codec, jpeg_quality, png_level)
    return out


def compressed_array(msg, topic: str = "image") -> np.ndarray:
    """Decode a ``CompressedImage``: ``uint8 [h, w, 3]`` BGR, or ``[h, w]`` when mono8.

    Raises:
        ImageDataError: The data is not an image OpenCV can decode.
    """
    data = np.frombuffer(bytes(msg.data), dtype=np.uint8)
    image = cv2.imdecode(data, cv2.IMREAD_UNCHANGED) if data.size else None
    if image is None:
        raise ImageDataError(topic, "data", f"{data.size} bytes", f"does not decode ({msg.format})")
    if image.ndim == 3 and image.shape[2] == 4:
        image = cv2.cvtColor(image, cv2.COLOR_BGRA2BGR)
    return image


def frame_array(msg, msgtype: str, topic: str = "image") -> np.ndarray:
    """The pixels of a camera frame of either type (:data:`IMAGE_TYPE`, :data:`COMPRESSED_TYPE`).

    Raises:
        ImageDataError: The frame does not decode, or ``msgtype`` is neither type.
    """
    if msgtype == COMPRESSED_TYPE:
        return compressed_array(msg, topic)
    if msgtype == IMAGE_TYPE:
        return raw_array(msg, topic)
    raise ImageDataError(topic, "type", msgtype, f"expected {IMAGE_TYPE} or {COMPRESSED_TYPE}")


def fill_raw(image: np.ndarray, out, header):
    """Fill ``out`` (a fresh ``sensor_msgs/Image``) with a decoded frame (bgr8 or mono8)."""
    arr = np.ascontiguousarray(image, dtype=np.uint8)
    out.header = header
    out.height, out.width = arr.shape[:2]
    out.encoding = "mono8" if arr.ndim == 2 else "bgr8"
    out.is_bigendian = 0
    out.step = arr.shape[1] * (1 if arr.ndim == 2 else 3)
    out.data = arr.tobytes()
    return out
