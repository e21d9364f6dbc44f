"""Offline evaluation and evolution of ANT excavation controllers (imports no rclpy)."""
