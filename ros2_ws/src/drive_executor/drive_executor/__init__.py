"""The drive executor: a behaviour word as wheel motion (docs/architecture.md, "Field execution").

Pure modules (no ``rclpy``): :mod:`~drive_executor.params` (the node's parameters),
:mod:`~drive_executor.primitives` (closed-loop motion primitives in the manner of nav2's
DriveOnHeading and Spin), :mod:`~drive_executor.core` (a word as a queue of primitives,
the safety gate and the override), :mod:`~drive_executor.goals` (the tick goal's encoding).
The ROS node is :mod:`~drive_executor.executor_node`.
"""
