"""The synthetic camera's calibration for full perception (paper, 6.2).

With full perception the controllers never see the simulator's truth: the simulator
publishes it under ``/truth`` (or ``/snapshot``), the ``sensors`` node renders what the
dome's overhead camera and laser would deliver, and the overhead localiser and the terrain
mapper turn that back into ``/robot_k/pose`` and ``/worksite/height_map``
(:func:`excavation_bringup.graph.lockstep`, :func:`excavation_bringup.graph.continuous`).
The camera is calibrated first, as in the field: :func:`simulated_calibration`.
"""

from __future__ import annotations

import numpy as np


def simulated_calibration(blueprint, seed: int, camera_info: bool = False):
    """The synthetic camera over ``blueprint``'s site, calibrated from surveyed marks.

    As in the field: marks at known places are "clicked" in a frame (with pixel noise,
    seeded by ``seed``) and :func:`overhead_localizer.camera_model.calibrate` fits the
    model. ``ant-dome up --sim`` uses the same model as this trial. With ``camera_info``
    (a camera that publishes its intrinsics, as the rehearsal's emulated driver does) only
    the pose is fitted, under the driver's K and D, as ``calibrate --camera-info`` does in
    the dome: a model whose own fitted intrinsics differ from the driver's makes the
    localiser warn at start and keep the file's.
    """
    from excavation_sim.camera import (
        CameraParams,
        OverheadCamera,
        calibration_marks,
        default_beacons,
    )
    from overhead_localizer.camera_model import calibrate, fit_pose

    rows, cols = blueprint.shape
    params = CameraParams.for_site(cols * blueprint.cell_size, rows * blueprint.cell_size)
    camera = OverheadCamera(params, default_beacons(), rows, cols, blueprint.cell_size, seed)
    pixels, points = calibration_marks(camera, np.random.default_rng([seed, 1]))
    size = (params.width, params.height)
    if camera_info:
        return fit_pose(pixels, points, size, params.camera_matrix(), params.dist_coeffs())
    return calibrate(pixels, points, size)
