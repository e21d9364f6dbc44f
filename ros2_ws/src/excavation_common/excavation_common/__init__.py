"""What every ROS package of the suite shares (docs/architecture.md, "Packages").

* :mod:`excavation_common.errors`: the base error type every loader and node raises;
* :mod:`excavation_common.constants`: grid, zone and blade codes, ``BladeGeometry``;
* :mod:`excavation_common.frames`: grid cells and headings <-> the ``map`` frame;
* :mod:`excavation_common.messages`: message <-> array conversions (no ``rclpy``);
* :mod:`excavation_common.files`: atomic file writes;
* :mod:`excavation_common.params`: node parameters declared from frozen dataclasses;
* :mod:`excavation_common.ros`: QoS profiles, spin and shutdown, the diagnostics helper
  (the only module here that imports ``rclpy``).

This package imports no other package of the project.
"""
