"""The blade tests' behaviour words and nodes: the team's supervisor, a blade driver and a
probe that talks to the driver as a controller, an operator and a monitor do.

The node factories take the ``ros`` fixture (``tests/conftest.py``) and add their node to
its executor.
"""

from __future__ import annotations


def word(*bits: int) -> int:
    """The behaviour word with ``bits`` set (``word(MOVE_FORWARD, BLADE_BELOW_CMD)``)."""
    return sum(1 << b for b in bits)


def blade_supervisor(ros, armed: bool = True):
    """The team's supervisor (one robot, no pose watching), armed at start unless told
    otherwise."""
    from rclpy.parameter import Parameter

    from team_supervisor.supervisor_node import SupervisorNode

    return ros.add(
        SupervisorNode(
            context=ros.context,
            parameter_overrides=[
                Parameter("robots", value=1),
                Parameter("watch_poses", value=False),
                Parameter("arm_at_start", value=armed),
            ],
        )
    )


def blade_driver_node(ros, supervised: bool = True, **params):
    """Robot 0's blade driver (namespace ``/robot_0``) with parameters ``params``.

    Args:
        ros: The ``ros`` fixture.
        supervised: Start an armed :func:`blade_supervisor` first (the default).
        params: Parameter overrides, e.g. ``backend="sim"``.
    """
    from rclpy.parameter import Parameter

    from blade_driver.driver_node import BladeDriverNode

    if supervised:
        blade_supervisor(ros)
    return ros.add(
        BladeDriverNode(
            context=ros.context,
            namespace="/robot_0",
            parameter_overrides=[Parameter(k, value=v) for k, v in params.items()],
        )
    )


def blade_probe(ros):
    """A node that talks to robot 0's driver like a controller, an operator and a monitor.

    It keeps what the driver publishes in ``joints`` (its joint states), ``servo`` (its
    set-points) and ``diags`` (its diagnostics statuses), and has publishers ``behaviour``
    (the controller's word), ``override`` (the operator's set-point) and ``state`` (the
    simulator's servo state).
    """
    from diagnostic_msgs.msg import DiagnosticArray
    from excavation_interfaces.msg import BladeCommand
    from rclpy.node import Node
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64MultiArray, UInt16

    node = ros.add(Node("probe", context=ros.context))
    node.joints, node.servo, node.diags = [], [], []
    node.create_subscription(JointState, "/robot_0/blade/joint_states", node.joints.append, 10)
    node.create_subscription(BladeCommand, "/robot_0/blade/servo_command", node.servo.append, 10)
    node.create_subscription(
        DiagnosticArray,
        "/diagnostics",
        lambda m: node.diags.extend(s for s in m.status if s.name.endswith("blade_driver")),
        10,
    )
    node.behaviour = node.create_publisher(UInt16, "/robot_0/behaviour", 10)
    node.override = node.create_publisher(Float64MultiArray, "/robot_0/blade/commands", 10)
    node.state = node.create_publisher(JointState, "/robot_0/blade/servo_state", 10)
    return node
