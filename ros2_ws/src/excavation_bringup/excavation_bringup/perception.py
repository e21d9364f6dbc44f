"""The perception chain of ``ant-trial --perception full`` (paper, 6.2), as composable nodes.

With full perception the controllers never see the simulator's truth. The simulator
publishes it under ``/truth`` (``truth_prefix``); the ``sensors`` node renders from it what
the dome's overhead camera and laser would deliver; the overhead localizer and the terrain
mapper turn that back into ``/robot_k/pose`` and ``/worksite/height_map``, the topics the
controllers read. The camera is calibrated first, as in the field: marks at known places
are "clicked" in a frame (with pixel noise) and :func:`overhead_localizer.camera_model.calibrate`
fits the model the localizer loads.

The mapper starts from a level site (``prior_height`` 0: the survey before the robots
enter), so the cells under the robots' start positions have a value before any beam
reaches them.
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


def perception_nodes(
    context, robots: int, seed: int, blueprint, truth_prefix: str = SIM_TRUTH_PREFIX
) -> list:
    """Sensors, localizer and mapper nodes for a trial on ``context``.

    Args:
        context: The rclpy context of the trial.
        robots: Number of robots.
        seed: Seed of the sensors' noise and of the calibration marks.
        blueprint: The trial's :class:`blueprint_server.blueprint.Blueprint`.
        truth_prefix: Where the sensors read the truth they render (the continuous trial:
            the ``dynamics`` node's snapshots, ``/snapshot``).
    """
    from rclpy.parameter import Parameter

    from excavation_sim.camera import (
        CameraParams,
        OverheadCamera,
        calibration_marks,
        default_beacons,
    )
    from excavation_sim.sensors_node import SensorsNode
    from overhead_localizer.camera_model import calibrate, save_model
    from overhead_localizer.localizer_node import LocalizerNode
    from terrain_mapper.mapper_node import MapperNode

    rows, cols = blueprint.shape
    params = CameraParams.for_site(cols * blueprint.cell_size, rows * blueprint.cell_size)
    camera = OverheadCamera(params, default_beacons(), rows, cols, blueprint.cell_size, seed)
    pixels, points = calibration_marks(camera, np.random.default_rng([seed, 1]))
    model = calibrate(pixels, points, (params.width, params.height))
    fd, calibration = tempfile.mkstemp(prefix="ant-trial-camera-", suffix=".yaml")
    os.close(fd)
    try:
        save_model(model, calibration)
        localizer = LocalizerNode(
            context=context,
            parameter_overrides=[
                Parameter("robots", value=robots),
                Parameter("calibration", value=calibration),
                Parameter("reliable", value=True),
            ],
        )  # loads the calibration now
    finally:
        os.unlink(calibration)
    sensors = SensorsNode(
        context=context,
        parameter_overrides=[
            Parameter("robots", value=robots),
            Parameter("seed", value=seed),
            Parameter("truth_prefix", value=truth_prefix),
            Parameter("sweep_scans", value=TRIAL_SWEEP_SCANS),
            Parameter("cell_size", value=float(blueprint.cell_size)),
            Parameter("rows", value=rows),
            Parameter("cols", value=cols),
            Parameter("reliable", value=True),
        ],
    )
    mapper = MapperNode(
        context=context,
        parameter_overrides=[
            Parameter("robots", value=robots),
            Parameter("rows", value=rows),
            Parameter("cols", value=cols),
            Parameter("cell_size", value=float(blueprint.cell_size)),
            Parameter("mount_x", value=float(sensors.laser_params.mount[0])),
            Parameter("mount_y", value=float(sensors.laser_params.mount[1])),
            Parameter("mount_z", value=float(sensors.laser_params.mount[2])),
            Parameter("sweep_scans", value=sensors.laser_params.sweep_scans),
            Parameter("prior_height", value=0.0),
            Parameter("robot_height", value=float(sensors.laser_params.robot_height)),
            Parameter("publish_map_info", value=False),
            Parameter("pose_wait", value=2.0),
            Parameter("reliable", value=True),
        ],
    )
    return [sensors, localizer, mapper]
