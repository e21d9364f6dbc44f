"""Whole episodes through ROS messages and ControllerCore equal the offline evaluator."""

from __future__ import annotations

import numpy as np
import pytest

from ant_controller.controller import Controller, ControllerCore
from ant_controller.genome_io import load_genome
from ant_controller.sensing import blade_volume
from ant_evolution.evaluate import ScenarioSet
from blueprint_server.blueprint import DIG, default_blueprint
from excavation_common.constants import BladeGeometry
from excavation_common.messages import (
    blade_from_joint,
    blade_joint,
    grid_to_image,
    heights_to_units,
    image_to_grid,
    pose_message,
    pose_to_grid,
)
from excavation_sim.world import BLADE, COL, HEADING, MEMORY, ROW, STUCK

CELL = 0.25
UNIT = 0.05
GEOMETRY = BladeGeometry()


def through_messages(world, k):
    """What robot k's controller node would decode from the simulator's messages."""
    heights_msg = grid_to_image(world.heights * UNIT, "32FC1")
    goal_m = np.where(world.zones == DIG, world.goal * UNIT, np.nan)
    goal_msg = grid_to_image(goal_m, "32FC1")
    zones_msg = grid_to_image(world.zones, "mono8")
    poses = np.array(
        [
            pose_to_grid(pose_message(r[ROW], r[COL], r[HEADING], CELL, 0.01, 0.01), CELL)
            for r in world.robots
        ]
    )
    r = world.robots[k]
    force = blade_volume(world.heights, r[ROW], r[COL], r[HEADING], r[BLADE]) * (
        GEOMETRY.max_force / 24
    )
    blade, volume = blade_from_joint(blade_joint(r[BLADE], force, GEOMETRY), GEOMETRY)
    shape = world.heights.shape
    heights = heights_to_units(image_to_grid(heights_msg, "32FC1", shape=shape), UNIT)
    goal = heights_to_units(image_to_grid(goal_msg, "32FC1", shape=shape), UNIT)
    zones = image_to_grid(zones_msg, "mono8", shape=shape)
    return heights, zones, goal, poses, blade, volume, bool(r[STUCK])


@pytest.mark.parametrize("kind", ["hand-coded", "genome"])
@pytest.mark.parametrize("robots", [1, 4])
def test_episode_through_messages_matches_offline(kind, robots):
    ctl = (
        Controller.hand_coded()
        if kind == "hand-coded"
        else Controller.from_genome(load_genome("genomes/best.json"))
    )
    sets = ScenarioSet.create(default_blueprint(2), robots, 2, 150, seed=21)
    offline = sets.score(ctl)
    for i in range(sets.size):
        world = sets.world(i)
        cores = [ControllerCore(ctl) for _ in range(robots)]
        for _ in range(150):
            masks = []
            for k in range(robots):
                heights, zones, goal, poses, blade, volume, stuck = through_messages(world, k)
                masks.append(cores[k].decide(heights, zones, goal, poses, k, blade, volume, stuck))
            world.step(masks)
            assert [c.memory for c in cores] == list(world.robots[:, MEMORY])
        assert world.fitness() == offline[i]
