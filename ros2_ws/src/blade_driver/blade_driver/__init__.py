"""Blade driver: behaviour words to blade servo set-points (ROS package ``blade_driver``)."""
