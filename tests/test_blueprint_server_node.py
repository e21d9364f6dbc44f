"""The blueprint server node: latched topics, reload, bad files, diagnostics."""

from __future__ import annotations

import math

import numpy as np
from diagnostic_msgs.msg import DiagnosticStatus
from helpers.diagnostics import DiagnosticsProbe
from nav_msgs.msg import MapMetaData
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import Image
from std_srvs.srv import Trigger

from blueprint_server.blueprint import default_blueprint
from blueprint_server.server_node import BlueprintServer
from excavation_common.messages import image_to_grid
from excavation_common.ros import LATCHED


def listener(ros):
    node = ros.add(Node("listener", context=ros.context))
    got = {"goal": [], "zones": [], "info": []}
    node.create_subscription(Image, "/blueprint/goal", got["goal"].append, LATCHED)
    node.create_subscription(Image, "/blueprint/zones", got["zones"].append, LATCHED)
    node.create_subscription(MapMetaData, "/worksite/map_info", got["info"].append, LATCHED)
    got["diag"] = DiagnosticsProbe(node).arrays
    return node, got


def test_late_joiner_gets_the_blueprint(ros):
    ros.add(
        BlueprintServer(
            context=ros.context, parameter_overrides=[Parameter("blueprint", value="default:2")]
        )
    )
    _, got = listener(ros)  # subscribes after the server published
    assert ros.spin_until(lambda: got["goal"] and got["zones"] and got["info"])
    bp = default_blueprint(2)
    zones = image_to_grid(got["zones"][-1], "mono8", shape=bp.shape)
    assert np.array_equal(zones, bp.zones)
    goal = image_to_grid(got["goal"][-1], "32FC1", shape=bp.shape)
    assert goal[4, 4] == np.float32(-2 * bp.height_unit)
    assert math.isnan(goal[0, 0])
    info = got["info"][-1]
    assert (info.width, info.height, info.resolution) == (16, 16, bp.cell_size)


def test_reload_keeps_the_last_good_blueprint(ros, tmp_path):
    site = tmp_path / "site.yaml"
    site.write_text("format: ant-blueprint/1\nrows:\n  - 'D1D'\n  - 'DDD'\n")
    server = ros.add(
        BlueprintServer(
            context=ros.context,
            parameter_overrides=[
                Parameter("blueprint", value=str(site)),
                Parameter("diagnostics_period", value=0.2),
            ],
        )
    )
    client_node, got = listener(ros)
    client = client_node.create_client(Trigger, "/blueprint_server/reload")
    assert ros.spin_until(lambda: got["zones"] and client.service_is_ready())
    site.write_text("format: ant-blueprint/1\nrows: [oops\n")
    future = client.call_async(Trigger.Request())
    assert ros.spin_until(future.done)
    response = future.result()
    assert not response.success
    assert str(site) in response.message and "still publishing" in response.message
    assert server.blueprint is not None and server.blueprint.shape == (2, 3)
    assert ros.spin_until(
        lambda: any(s.level == DiagnosticStatus.ERROR for a in got["diag"] for s in a.status)
    )
    site.write_text("format: ant-blueprint/1\nrows:\n  - 'D2DD'\n")
    future = client.call_async(Trigger.Request())
    assert ros.spin_until(future.done) and future.result().success
    assert ros.spin_until(lambda: got["zones"][-1].width == 4)
