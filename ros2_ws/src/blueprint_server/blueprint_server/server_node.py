"""``ros2 run blueprint_server server``: publishes the excavation blueprint, latched.

Topics (relative names; in the root namespace they are the absolute names of
``docs/interfaces.md``):

* ``blueprint/goal`` (sensor_msgs/Image 32FC1): goal height in metres per dig cell, NaN
  elsewhere; ``blueprint/zones`` (mono8): 0 don't care, 1 dig, 2 dump;
  ``worksite/map_info`` (nav_msgs/MapMetaData). All reliable, transient local, depth 1, so
  late joiners get the current blueprint.
* ``/diagnostics`` (diagnostic_msgs/DiagnosticArray): OK with the blueprint's name, or
  ERROR with the loader's message.

Service ``~/reload`` (std_srvs/Trigger) reloads the ``blueprint`` parameter's file. A bad
file keeps the last good blueprint published and reports the error in the response and on
``/diagnostics``.

Parameters: ``blueprint`` (file, ``default``, ``default:D`` or ``landing-pad``; default
``default``), ``diagnostics_period`` (s, default 1.0).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from nav_msgs.msg import MapMetaData
from rclpy.node import Node
from sensor_msgs.msg import Image
from std_srvs.srv import Trigger

from blueprint_server.blueprint import DIG, Blueprint, resolve_blueprint
from blueprint_server.errors import BlueprintError
from excavation_common.messages import grid_to_image, map_info
from excavation_common.params import param
from excavation_common.ros import LATCHED, declare_params, diagnostics, spin_node


def blueprint_messages(bp: Blueprint, stamp=None) -> tuple[Image, Image, MapMetaData]:
    """The goal image, zones image and map info of a blueprint."""
    goal = np.where(bp.zones == DIG, bp.goal * bp.height_unit, np.nan).astype(np.float32)
    rows, cols = bp.shape
    return (
        grid_to_image(goal, "32FC1", stamp=stamp),
        grid_to_image(bp.zones, "mono8", stamp=stamp),
        map_info(rows, cols, bp.cell_size, stamp=stamp),
    )


@dataclass(frozen=True)
class ServerParams:
    """Parameters of the blueprint server (``config/server.yaml``)."""

    blueprint: str = param(
        "default",
        "default, default:D, landing-pad or a blueprint file; set it, then call ~/reload",
        read_only=False,
    )
    diagnostics_period: float = param(1.0, "s between status reports", low=0.01, high=3600.0)


class BlueprintServer(Node):
    """Loads a blueprint and publishes it latched; reloads on request."""

    def __init__(self, **kwargs) -> None:
        super().__init__("blueprint_server", **kwargs)
        self.params = declare_params(self, ServerParams, on_change=self.on_params)
        self.goal_pub = self.create_publisher(Image, "blueprint/goal", LATCHED)
        self.zones_pub = self.create_publisher(Image, "blueprint/zones", LATCHED)
        self.info_pub = self.create_publisher(MapMetaData, "worksite/map_info", LATCHED)
        self.diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.create_service(Trigger, "~/reload", self.on_reload)
        self.blueprint: Blueprint | None = None
        self.error: str | None = None
        self.load()
        self.create_timer(self.params.diagnostics_period, self.publish_diagnostics)

    def on_params(self, params: ServerParams) -> None:
        """A new ``blueprint`` value is taken by the next ``~/reload``."""
        self.params = params

    def load(self) -> bool:
        """(Re)load the blueprint parameter; publish on success, keep the old one on error."""
        spec = self.params.blueprint
        try:
            bp = resolve_blueprint(spec)
        except BlueprintError as exc:
            self.error = str(exc)
            self.get_logger().error(f"blueprint not loaded: {exc}")
            self.publish_diagnostics()
            return False
        self.blueprint, self.error = bp, None
        goal, zones, info = blueprint_messages(bp, self.get_clock().now().to_msg())
        self.goal_pub.publish(goal)
        self.zones_pub.publish(zones)
        self.info_pub.publish(info)
        self.get_logger().info(f"published {bp.name}: {bp.shape[0]} x {bp.shape[1]} cells")
        self.publish_diagnostics()
        return True

    def on_reload(self, request: Trigger.Request, response: Trigger.Response):
        """``~/reload``: success and the blueprint's name, or the error (old one kept)."""
        response.success = self.load()
        if response.success:
            response.message = f"loaded {self.blueprint.name}"
        else:
            kept = self.blueprint.name if self.blueprint else "none"
            response.message = f"{self.error} (still publishing: {kept})"
        return response

    def publish_diagnostics(self) -> None:
        """One status: OK with the blueprint, or ERROR with the last load error."""
        values = {}
        if self.blueprint is not None:
            rows, cols = self.blueprint.shape
            values = {
                "blueprint": self.blueprint.name,
                "cells": f"{rows}x{cols}",
                "dig_cells": self.blueprint.dig_cells,
            }
        if self.error is None and self.blueprint is not None:
            level, message = DiagnosticStatus.OK, f"publishing {self.blueprint.name}"
        else:
            level, message = DiagnosticStatus.ERROR, self.error or "no blueprint"
        self.diag_pub.publish(diagnostics(self, level, message, values, "worksite"))


def main(args: list[str] | None = None) -> int:
    """Entry point of ``ros2 run blueprint_server server``."""
    return spin_node(BlueprintServer, args)


if __name__ == "__main__":
    sys.exit(main())
