"""Parameters of the ``mapper`` node besides the grid and estimation settings (no ``rclpy``).

:class:`MapperNodeParams` (topics, sweep, mount synchronisation, QoS) and
:class:`terrain_mapper.mapper.MapperParams` (grid, mount, estimation) are declared together
by ``excavation_common.ros.declare_params``; ``config/mapper.yaml`` states every default,
and ``excavation_bringup.site`` generates them from a site file.
"""

from __future__ import annotations

from dataclasses import dataclass

from excavation_common.params import param
from terrain_mapper.geometry import PAN_JOINT, TILT_JOINT


@dataclass(frozen=True)
class MapperNodeParams:
    """Topics, sweeps and QoS of the mapper node.

    Attributes:
        robots: ``/robot_k/pose``, k < robots, are masked out of the scans.
        sweep_scans: Scans per sweep; a map is published after each sweep.
        pose_wait: Seconds a finished sweep waits for poses as new as its first scan.
        scan_topic: ``sensor_msgs/LaserScan`` of the overhead laser.
        mount_topic: ``sensor_msgs/JointState`` of its pan/tilt mount.
        pan_joint: The pan joint's name in the mount's JointState.
        tilt_joint: The tilt joint's name in the mount's JointState.
        scan_stamp_offset: Seconds added to every scan's stamp before it is matched to
            the mount states (the scanner's clock behind the mount's: positive); the
            map's stamp is the corrected one.
        mount_max_gap: Seconds between two mount states across which the angles are still
            interpolated (a longer gap: the scans in it are dropped and counted).
        mount_wait: Seconds a scan waits for a mount state after its stamp: it is given up
            once the laser has sent a scan stamped that much later, or has waited that
            long in wall time with nothing queued (both streams stopped).
        publish_map_info: Also publish ``/worksite/map_info`` (off: the blueprint server
            owns it; on only for a mapper used without one).
        reliable: Reliable QoS with ``queue`` depth for scans and mount states.
        queue: Queue depth with ``reliable``.
        diagnostics_period: Seconds between ``/diagnostics`` reports.
    """

    robots: int = param(4, "robots whose footprints are masked", low=0, high=64)
    sweep_scans: int = param(64, "scans per sweep", low=2, high=100000)
    pose_wait: float = param(0.5, "s a sweep waits for current poses", low=0.0, high=60.0)
    scan_topic: str = param("/worksite/scan", "LaserScan topic")
    mount_topic: str = param("/worksite/laser_mount/joint_states", "mount JointState topic")
    pan_joint: str = param(PAN_JOINT, "pan joint's name in the mount JointState")
    tilt_joint: str = param(TILT_JOINT, "tilt joint's name in the mount JointState")
    scan_stamp_offset: float = param(
        0.0, "s added to a scan's stamp before it is matched to mount states"
    )
    mount_max_gap: float = param(0.2, "s: widest gap between mount states interpolated", low=0.0)
    mount_wait: float = param(
        1.0, "s a scan waits for a later mount state (stamps; wall if nothing queued)", low=0.0
    )
    publish_map_info: bool = param(False, "publish /worksite/map_info (the server owns it)")
    reliable: bool = param(False, "reliable QoS with queue depth (else sensor data)")
    queue: int = param(200, "queue depth with reliable", low=1, high=100000)
    diagnostics_period: float = param(1.0, "s between diagnostics", low=0.01, high=3600.0)
