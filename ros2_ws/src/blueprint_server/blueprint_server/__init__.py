"""Excavation blueprints (zones, goal depths) and the blueprint server node."""
