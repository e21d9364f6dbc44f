"""Bag tools: record, replay and report trials as ROS 2 bags with MCAP storage.

Split as ``rosbags.rosbag2`` is: ``topics`` (suite topics, type store), ``metadata``
(QoS profiles, ``metadata.yaml``), ``writer`` and ``reader`` (bag directories, pure, no
``rclpy``), ``recover``, ``images`` (camera frames as CompressedImage), ``errors``;
``recorder_node`` and ``player_node`` are the ROS nodes; ``trial_data`` turns a trial's bag
into per-tick arrays; ``report`` draws and summarises it; ``cli`` is the ``ant-bag``
command. docs/bags.md is the user's guide.
"""
