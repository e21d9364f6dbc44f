"""The registry of node kinds: every node a trial or the dome can run, registered once.

A node kind names the package that ships it, the module that ``python -m`` (or ``ros2 run``)
starts, the node class that a composed launcher builds in-process, and the parameter
dataclasses that the node declares (``excavation_common.params``). Everything else derives
from this table: the node specs of the trial graph (``excavation_bringup.nodes``), the
generated ``config/*.yaml`` files and the parameter tables of ``docs/interfaces.md``, and the
one test that checks them. ``docs/architecture.md`` ("Node kinds") lists the table.

Adding a node kind is one entry here and one node spec function in ``nodes``.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass


@dataclass(frozen=True)
class NodeKind:
    """One kind of node.

    Attributes:
        name: Registry key (``controller``, ``team_tick``...); the graph's node names
            derive from it (``controller_1``). The ROS node name is the node class's own
            (``blueprint_server`` for ``server``, ``bag_recorder`` for ``recorder``).
        package: The ament package that installs it.
        module: The module whose ``main`` starts it (``python -m MODULE``).
        node_class: Name of the node class in ``module`` (``ControllerNode``).
        params: ``module:Class`` of each parameter dataclass it declares, in declaration
            order (a node may declare a topic/config set and a tuning set).
        executable: The console script ``ros2 run PACKAGE EXECUTABLE`` starts.
        config: The package's parameter file (``config/NAME.yaml``), generated from
            ``params``; empty when the kind ships none.
    """

    name: str
    package: str
    module: str
    node_class: str
    params: tuple[str, ...]
    executable: str
    config: str = ""

    def load_class(self) -> type:
        """The node class (imports the node's module)."""
        return getattr(importlib.import_module(self.module), self.node_class)

    def param_classes(self) -> tuple[type, ...]:
        """The parameter dataclasses (imports their modules)."""
        out = []
        for ref in self.params:
            module, name = ref.split(":")
            out.append(getattr(importlib.import_module(module), name))
        return tuple(out)


KINDS: dict[str, NodeKind] = {
    kind.name: kind
    for kind in (
        NodeKind(
            "controller",
            "ant_controller",
            "ant_controller.controller_node",
            "ControllerNode",
            ("ant_controller.input_gate:ControllerParams",),
            "controller",
            "controller.yaml",
        ),
        NodeKind(
            "blade_driver",
            "blade_driver",
            "blade_driver.driver_node",
            "BladeDriverNode",
            ("blade_driver.params:DriverNodeParams",),
            "driver",
            "driver.yaml",
        ),
        NodeKind(
            "executor",
            "drive_executor",
            "drive_executor.executor_node",
            "ExecutorNode",
            ("drive_executor.params:ExecutorParams",),
            "executor",
            "executor.yaml",
        ),
        NodeKind(
            "team_tick",
            "team_tick",
            "team_tick.node",
            "TeamTickNode",
            ("team_tick.core:TeamTickParams", "team_tick.node:TeamTickNodeParams"),
            "team_tick",
            "team_tick.yaml",
        ),
        NodeKind(
            "supervisor",
            "team_supervisor",
            "team_supervisor.supervisor_node",
            "SupervisorNode",
            ("team_supervisor.supervisor_node:SupervisorParams",),
            "supervisor",
            "supervisor.yaml",
        ),
        NodeKind(
            "server",
            "blueprint_server",
            "blueprint_server.server_node",
            "BlueprintServer",
            ("blueprint_server.server_node:ServerParams",),
            "server",
            "server.yaml",
        ),
        NodeKind(
            "sim",
            "excavation_sim",
            "excavation_sim.sim_node",
            "SimNode",
            ("excavation_sim.lockstep:SimParams",),
            "sim",
            "sim.yaml",
        ),
        NodeKind(
            "dynamics",
            "excavation_sim",
            "excavation_sim.dynamics_node",
            "DynamicsNode",
            (
                "excavation_sim.dynamics_node:DynamicsNodeParams",
                "excavation_sim.dynamics:DynamicsParams",
                "excavation_sim.soil:SoilParams",
            ),
            "dynamics",
            "dynamics.yaml",
        ),
        NodeKind(
            "sensors",
            "excavation_sim",
            "excavation_sim.sensors_node",
            "SensorsNode",
            ("excavation_sim.sensors_node:SensorsParams",),
            "sensors",
        ),
        NodeKind(
            "localizer",
            "overhead_localizer",
            "overhead_localizer.localizer_node",
            "LocalizerNode",
            (
                "overhead_localizer.params:LocalizerNodeParams",
                "overhead_localizer.localize:LocalizerParams",
            ),
            "localizer",
            "localizer.yaml",
        ),
        NodeKind(
            "mapper",
            "terrain_mapper",
            "terrain_mapper.mapper_node",
            "MapperNode",
            ("terrain_mapper.params:MapperNodeParams", "terrain_mapper.mapper:MapperParams"),
            "mapper",
            "mapper.yaml",
        ),
        NodeKind(
            "recorder",
            "excavation_bags",
            "excavation_bags.recorder_node",
            "RecorderNode",
            ("excavation_bags.recorder_node:RecorderParams",),
            "ant-bag",
            "bag_recorder.yaml",
        ),
        NodeKind(
            "player",
            "excavation_bags",
            "excavation_bags.player_node",
            "PlayerNode",
            ("excavation_bags.player_node:PlayerParams",),
            "ant-bag",
            "bag_player.yaml",
        ),
        NodeKind(
            "emulated_base",
            "dome_emulator",
            "dome_emulator.base_node",
            "BaseNode",
            ("dome_emulator.base:BaseParams",),
            "base",
        ),
        NodeKind(
            "emulated_servo_board",
            "dome_emulator",
            "dome_emulator.servo_board_node",
            "ServoBoardNode",
            ("dome_emulator.servo_board:ServoBoardParams",),
            "servo_board",
        ),
        NodeKind(
            "emulated_camera",
            "dome_emulator",
            "dome_emulator.camera_node",
            "CameraNode",
            ("dome_emulator.camera:CameraEmulatorParams",),
            "camera",
        ),
        NodeKind(
            "emulated_laser",
            "dome_emulator",
            "dome_emulator.laser_node",
            "LaserNode",
            ("dome_emulator.laser:LaserEmulatorParams",),
            "laser",
        ),
    )
}
"""Every node kind, by name."""


def kind(name: str) -> NodeKind:
    """The registered node kind ``name``.

    Raises:
        KeyError: No such kind (the message lists the registered ones).
    """
    try:
        return KINDS[name]
    except KeyError:
        raise KeyError(f"no node kind {name!r}; registered: {', '.join(KINDS)}") from None
