"""Bag tools: record, replay and report trials as ROS 2 bags with MCAP storage.

``storage`` writes and reads bag directories (pure, no ``rclpy``); ``recorder_node`` and
``player_node`` are the ROS nodes; ``trial_data`` turns a trial's bag into per-tick arrays;
``report`` draws and summarises it; ``cli`` is the ``ant-bag`` command. docs/bags.md is the
user's guide.
"""
