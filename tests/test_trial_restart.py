"""Killing a controller mid-trial: the simulator idles that robot, reports it, and a
restarted controller rejoins. With blade drivers, the orphaned robot's blade also goes home
(the driver's watchdog, in simulated time).

Every node shares one executor here, so a tick's timeout and a live controller's word can
both be ready when a loaded machine resumes the process: while every controller lives the
simulator waits 30 s for a word (no live robot can miss one), and only while the victim is
dead, and until the restarted one has sent its first word, does it give up after 0.3 s, so
that the test sees several idled ticks quickly.
"""

from __future__ import annotations

import pytest
from helpers.diagnostics import DiagnosticsProbe
from helpers.rigs import controller_node
from rclpy.node import Node
from rclpy.parameter import Parameter
from std_msgs.msg import UInt16

from ant_controller.layout import BLADE_HOME
from blueprint_server.server_node import BlueprintServer
from excavation_sim.sim_node import SimNode


def controller(ros, k):
    return controller_node(ros, k, 2)


@pytest.mark.parametrize("drivers", [False, True])
def test_killed_controller_idles_then_rejoins(ros, drivers):
    from blade_driver.driver_node import BladeDriverNode
    from excavation_sim.world import BLADE
    from team_supervisor.supervisor_node import SupervisorNode

    ros.add(
        SupervisorNode(
            context=ros.context,
            parameter_overrides=[
                Parameter("robots", value=2),
                Parameter("arm_at_start", value=True),
            ],
        )
    )
    ros.add(BlueprintServer(context=ros.context))
    sim = ros.add(
        SimNode(
            context=ros.context,
            parameter_overrides=[
                Parameter("robots", value=2),
                Parameter("steps", value=400),
                Parameter("command_timeout", value=30.0),
                Parameter("blade_driver", value=drivers),
            ],
        )
    )
    if drivers:
        for k in range(2):
            ros.add(BladeDriverNode(context=ros.context, namespace=f"/robot_{k}"))
    words = []
    watcher = ros.add(Node("watcher", context=ros.context))
    watcher.create_subscription(UInt16, "/robot_1/behaviour", words.append, 10)
    reports = DiagnosticsProbe(watcher).named("/sim")
    controller(ros, 0)
    victim = controller(ros, 1)
    assert ros.spin_until(lambda: sim.tick >= 5, timeout=30)
    assert sim.missed == {0: 0, 1: 0}
    ros.executor.remove_node(victim)  # the process dies
    victim.destroy_node()
    killed_at, missed_0 = sim.tick, sim.missed[0]
    sim.clock.timeout = 0.3  # see the module docstring
    assert ros.spin_until(lambda: sim.missed[1] >= 3, timeout=30)
    # The others keep stepping: robot 0 answered the ticks robot 1 missed (on a loaded
    # machine the 0.3 s timeout may take one of its words too, never most of them).
    assert sim.tick > killed_at and sim.missed[0] - missed_0 < sim.missed[1]
    assert any("no command from robots [1]" in r.message for r in reports)
    if drivers:
        assert sim.world.robots[1, BLADE] == BLADE_HOME
        assert sim.missed_servo[0] == 0 and sim.missed_servo[1] >= 1
    heard = len(words)
    controller(ros, 1)  # restarted
    assert ros.spin_until(lambda: len(words) > heard, timeout=60)  # its first word
    sim.clock.timeout = 30.0
    missed, missed_0, joined_at = sim.missed[1], sim.missed[0], sim.tick
    assert ros.spin_until(lambda: sim.tick >= joined_at + 10, timeout=120)
    assert sim.missed[1] <= missed + 1  # at most the tick its first word came in
    assert sim.missed[0] == missed_0
