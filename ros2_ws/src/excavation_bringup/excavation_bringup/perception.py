"""The perception chain of ``ant-trial --perception full`` (paper, 6.2), as composable nodes.

With full perception the controllers never see the simulator's truth. The simulator
publishes it under ``/truth`` (``truth_prefix``); the ``sensors`` node renders from it what
the dome's overhead camera and laser would deliver; the overhead localizer and the terrain
mapper turn that back into ``/robot_k/pose`` and ``/worksite/height_map``, the topics the
controllers read. The camera is calibrated first, as in the field: marks at known places
are "clicked" in a frame (with pixel noise) and :func:`overhead_localizer.camera_model.calibrate`
fits the model the localizer loads.

The mapper starts from a level site (``prior_known``, ``prior_height`` 0: the survey
before the robots enter), so the cells under the robots' start positions have a value
before any beam reaches them.
"""

from __future__ import annotations

import os
import tempfile

import numpy as np

SIM_TRUTH_PREFIX = "/truth"
"""Where the simulator publishes its truth in full-perception mode."""

TRIAL_SWEEP_SCANS = 32
"""Scans per laser sweep in a trial: half the default, since every message costs the
trial's single executor a few milliseconds; one such sweep still measures every cell not
under a robot to 0.05 soil unit RMSE (docs/perception.md)."""

POSE_WAIT = 2.0
"""Wall seconds a finished laser sweep waits for the localizer's poses of the same instant
before the mapper fuses it with the poses it has (composed trials: one executor, so the
poses of a frame come within milliseconds, and a robot hidden from the camera costs each
sweep only this long)."""

PROCESS_POSE_WAIT = 30.0
""":data:`POSE_WAIT` when the perception nodes are processes (``--processes``, ``ant-dome up
--sim``). A loaded 2-core machine can keep the localizer process more than 2 s behind the
mapper; a sweep fused then masks the robots where they stood the tick before, and the
height map (hence the words) differ from the composed trial's (seen in CI: ``ant-dome up
--sim`` diverged from ``ant-trial`` at tick 22 of 40; with the 1 s camera stall of
tests/test_faults.py every robot lost a tick). A fallback only: current poses end the
wait at once."""


RETAKES = 2
"""Frames of one instant the localizer may ask the synthetic camera for when a robot it was
tracking is not seen (``retakes``). One frame per tick means a robot hidden by one frame's
glare (about 1 robot-frame in 2,000, docs/perception.md) would hold a lockstep team for a
whole tick timeout; a second frame of the same instant has its own glare."""

RELIABLE_MOUNT_WAIT = 10.0
"""Seconds a laser scan waits for the mount state of its stamp before the mapper drops it
(the mapper's default: 1 s): of the laser's stamps, or of wall time once nothing is queued.
The trial's laser is reliable, so the state comes; the wait only bounds a mount that went
silent. It was raised from 1 s when a mapper held up for more than 1 s (seen at tick 0 of a
process trial, every node starting on the 2 cores) found the wait over before it had taken
the queued state, dropped the sweep's last scan and fused that sweep only when the next one
began: the whole team lost tick 0. The mapper now takes every queued message before it
gives a scan up (``terrain_mapper.mapper_node``), so this value no longer decides that. The
dome's ``--sim`` uses the same value (``excavation_bringup.site.mapper_params``)."""


def simulated_calibration(blueprint, seed: int):
    """The synthetic camera over ``blueprint``'s site, calibrated from surveyed marks.

    As in the field: marks at known places are "clicked" in a frame (with pixel noise,
    seeded by ``seed``) and :func:`overhead_localizer.camera_model.calibrate` fits the
    model. ``ant-dome up --sim`` uses the same model as this trial.
    """
    from excavation_sim.camera import (
        CameraParams,
        OverheadCamera,
        calibration_marks,
        default_beacons,
    )
    from overhead_localizer.camera_model import calibrate

    rows, cols = blueprint.shape
    params = CameraParams.for_site(cols * blueprint.cell_size, rows * blueprint.cell_size)
    camera = OverheadCamera(params, default_beacons(), rows, cols, blueprint.cell_size, seed)
    pixels, points = calibration_marks(camera, np.random.default_rng([seed, 1]))
    return calibrate(pixels, points, (params.width, params.height))


def perception_parameters(
    robots: int,
    seed: int,
    blueprint,
    calibration: str,
    occlude: str = "",
    processes: bool = False,
) -> dict:
    """Parameters of the sensors, localizer and mapper of a lockstep trial.

    Calibrates the camera (as :func:`perception_nodes` does) and writes the model to
    ``calibration``, which the localizer's parameters name. Both trial modes use this:
    composed nodes get the values as parameter overrides, processes as ``-p`` arguments.

    Args:
        robots: Number of robots.
        seed: Seed of the sensors' noise and of the calibration marks.
        blueprint: The trial's :class:`blueprint_server.blueprint.Blueprint`.
        calibration: Path of the camera model file to write.
        occlude: LEDs hidden from the camera (the sensors node's ``occlude``).
        processes: The nodes run as processes (the mapper's ``pose_wait`` is then
            :data:`PROCESS_POSE_WAIT`, else :data:`POSE_WAIT`).

    Returns:
        ``{"sensors": {...}, "localizer": {...}, "mapper": {...}}``: name -> value.
    """
    from excavation_sim.laser import LaserParams
    from overhead_localizer.camera_model import save_model

    rows, cols = blueprint.shape
    cell = float(blueprint.cell_size)
    save_model(simulated_calibration(blueprint, seed), calibration)
    laser = LaserParams.for_site(rows, cols, cell, sweep_scans=TRIAL_SWEEP_SCANS)
    return {
        "sensors": {
            "robots": robots,
            "seed": seed,
            "truth_prefix": SIM_TRUTH_PREFIX,
            "sweep_scans": laser.sweep_scans,
            "cell_size": cell,
            "rows": rows,
            "cols": cols,
            "reliable": True,
            **({"occlude": occlude} if occlude else {}),  # "-p occlude:=" would not parse
        },
        "localizer": {
            "robots": robots,
            "calibration": calibration,
            "reliable": True,
            "retakes": RETAKES,
        },
        "mapper": {
            "robots": robots,
            "rows": rows,
            "cols": cols,
            "cell_size": cell,
            "mount_x": float(laser.mount[0]),
            "mount_y": float(laser.mount[1]),
            "mount_z": float(laser.mount[2]),
            "sweep_scans": laser.sweep_scans,
            "prior_known": True,
            "prior_height": 0.0,
            "robot_height": float(laser.robot_height),
            "publish_map_info": False,
            "pose_wait": PROCESS_POSE_WAIT if processes else POSE_WAIT,
            "mount_wait": RELIABLE_MOUNT_WAIT,
            "reliable": True,
        },
    }


def perception_nodes(
    context,
    robots: int,
    seed: int,
    blueprint,
    occlude: str = "",
    truth_prefix: str = SIM_TRUTH_PREFIX,
) -> list:
    """Sensors, localizer and mapper nodes for a trial on ``context``.

    Args:
        context: The rclpy context of the trial.
        robots: Number of robots.
        seed: Seed of the sensors' noise and of the calibration marks.
        blueprint: The trial's :class:`blueprint_server.blueprint.Blueprint`.
        occlude: LEDs hidden from the camera (the sensors node's ``occlude``).
        truth_prefix: Where the sensors read the truth they render (the continuous trial:
            the ``dynamics`` node's snapshots, ``/snapshot``).
    """
    from rclpy.parameter import Parameter

    from excavation_sim.sensors_node import SensorsNode
    from overhead_localizer.localizer_node import LocalizerNode
    from terrain_mapper.mapper_node import MapperNode

    def overrides(values: dict) -> list:
        return [Parameter(k, value=v) for k, v in values.items()]

    fd, calibration = tempfile.mkstemp(prefix="ant-trial-camera-", suffix=".yaml")
    os.close(fd)
    try:
        values = perception_parameters(robots, seed, blueprint, calibration, occlude)
        localizer = LocalizerNode(
            context=context, parameter_overrides=overrides(values["localizer"])
        )  # loads the calibration now
    finally:
        os.unlink(calibration)
    values["sensors"]["truth_prefix"] = truth_prefix
    sensors = SensorsNode(context=context, parameter_overrides=overrides(values["sensors"]))
    mapper = MapperNode(context=context, parameter_overrides=overrides(values["mapper"]))
    return [sensors, localizer, mapper]
