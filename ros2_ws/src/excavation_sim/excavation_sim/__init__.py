"""Simulated worksite: soil, robots, blade model, fitness and snapshots."""
