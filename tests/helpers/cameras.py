"""The synthetic overhead camera the camera and localizer tests share.

:func:`overhead_camera` builds it; :func:`camera` is the module-scoped fixture of it that
``tests/conftest.py`` registers for every test module (so a module asks for ``camera`` and
gets one camera for all its tests, built once).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import pytest

if TYPE_CHECKING:
    from excavation_sim.camera import OverheadCamera

CELL = 0.25
"""Cell size of the camera's 16 x 16 worksite, metres."""


def overhead_camera() -> OverheadCamera:
    """The default camera over a 16 x 16 worksite of 0.25 m cells, the shipped beacons,
    its sand texture from seed 0 (``camera.render`` takes the noise generator).

    Imported here, not at the top: ``tests/conftest.py`` imports this module for every
    test session, and most never look through a camera.
    """
    from excavation_sim.camera import CameraParams, OverheadCamera, default_beacons

    return OverheadCamera(CameraParams(), default_beacons(), 16, 16, CELL, seed=0)


@pytest.fixture(scope="module")
def camera() -> OverheadCamera:
    """:func:`overhead_camera`, one per test module."""
    return overhead_camera()
