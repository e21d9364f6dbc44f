"""Parameters of the ``localizer`` node besides the detection settings (no ``rclpy``).

:class:`LocalizerNodeParams` (topics, files, QoS, diagnostics) and
:class:`overhead_localizer.localize.LocalizerParams` (detection, pairing, tracking) are
declared together by ``excavation_common.ros.declare_params``; ``config/localizer.yaml``
states every default, and ``excavation_bringup.site`` generates them from a site file.
"""

from __future__ import annotations

from dataclasses import dataclass

from excavation_common.params import param

RETAKE_TOPIC = "/overhead/retake"
"""Where the localizer asks a camera for another frame of an instant (``retakes``)."""


@dataclass(frozen=True)
class LocalizerNodeParams:
    """Topics, files and QoS of the localizer node.

    Attributes:
        robots: Robots 0 .. robots - 1 are localized (the first entries of the LED table).
        calibration: Camera calibration YAML (``calibrate``); required, there is no default.
        beacons: LED table YAML; empty: the package's ``config/beacons.yaml``.
        image_topic: Camera frames (``sensor_msgs/Image``; with ``compressed``,
            ``sensor_msgs/CompressedImage``, conventionally ``<image>/compressed``).
        compressed: Frames arrive as jpeg or png ``CompressedImage``.
        camera_info_topic: The camera driver's ``sensor_msgs/CameraInfo``; empty: none.
            Frames wait for the first one. Its K and D are used when they agree with the
            calibration file's (a file fitted with ``calibrate --camera-info``); otherwise
            (K zero: an uncalibrated driver; other intrinsics than the ones the file's pose
            was fitted with) the file's are, and the camera's status is WARN saying why.
        use_height_map: The LED planes follow the soil under each robot.
        reliable: Reliable QoS (the lockstep trial); else best effort. Depth 1 either way.
        annotated_period: Seconds between annotated frames on ``/overhead/image_annotated``
            (jpeg, detected LEDs and poses drawn); 0: none.
        diagnostics_period: Seconds between ``/diagnostics`` reports.
        retakes: Frames of the same instant the node asks for on ``retake_topic`` when a
            robot it was tracking is not seen in a frame (a glare spot over one LED); the
            frame's poses are held until every tracked robot is seen or the retakes are
            spent. 0 (the default, a camera that streams): never. The trials' synthetic
            camera, which renders one frame per simulator tick, answers with a new frame of
            the same instant (its next noise and glare).
        retake_topic: ``excavation_interfaces/Retake`` stamped with the frame to take again.
    """

    robots: int = param(4, "robots localized (first entries of the LED table)", low=1, high=64)
    calibration: str = param("", "camera calibration YAML (required)")
    beacons: str = param("", "LED table YAML; empty: the package's config/beacons.yaml")
    image_topic: str = param("/overhead/image_raw", "camera frames")
    compressed: bool = param(False, "frames are sensor_msgs/CompressedImage (jpeg, png)")
    camera_info_topic: str = param(
        "", "CameraInfo; its K, D are used if they agree with the file's; empty: none"
    )
    use_height_map: bool = param(True, "LED planes follow the soil under each robot")
    reliable: bool = param(False, "reliable QoS for frames (else best effort); depth 1")
    annotated_period: float = param(
        0.0, "s between annotated frames on /overhead/image_annotated; 0: none", low=0.0
    )
    diagnostics_period: float = param(1.0, "s between diagnostics", low=0.01, high=3600.0)
    retakes: int = param(
        0, "frames of an instant asked for when a tracked robot is unseen", low=0, high=10
    )
    retake_topic: str = param(RETAKE_TOPIC, "Retake: the frame stamp to take again")
