"""Node-side helpers shared by the suite's nodes (this module imports rclpy; the core does not).

QoS profiles, :func:`spin_node` (init, build, spin, clean shutdown; a bad parameter or
input file at start is one line on stderr and exit code 2), :func:`declare_params` (a
frozen parameter dataclass declared with descriptors and kept valid at runtime) and
:func:`diagnostics` (the one ``/diagnostics`` helper every node uses) and
:func:`recorder_subscribes` (whether the bag recorder already hears a node's topics).
"""

from __future__ import annotations

import re
import sys
from collections.abc import Callable
from typing import Any, TypeVar

import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    ParameterType,
    SetParametersResult,
)
from rclpy.exceptions import (
    InvalidParameterTypeException,
    InvalidParameterValueException,
    ParameterUninitializedException,
)
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_sensor_data,
)

from excavation_common.errors import FieldError
from excavation_common.middleware import use_profiles
from excavation_common.params import ParameterError, specs, validate
from excavation_common.params import replace as replace_params

P = TypeVar("P")

LATCHED = QoSProfile(
    depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
)
"""QoS of latched maps (blueprint, map info, height map): reliable, transient local, depth 1."""

SENSOR_DATA = qos_profile_sensor_data
"""QoS of camera frames and laser scans: best effort, keep last 5."""

LATEST_FRAME = QoSProfile(
    depth=1, reliability=ReliabilityPolicy.BEST_EFFORT, history=HistoryPolicy.KEEP_LAST
)
"""QoS of a subscriber that only ever wants the newest camera frame (queue depth 1)."""

LATEST_STATE = QoSProfile(
    depth=1, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST
)
"""QoS of a subscriber that only ever wants the newest state of a stream (the emulated
sensors' world truth): a node busy rendering for longer than the stream's period takes the
newest message, not the oldest of a queue (with depth 10 and a 20 Hz world, frames showed
the world as it was 0.5 s before their stamps)."""

RECORDER_NODE = "bag_recorder"
"""Node name of the bag recorder (``excavation_bags``' recorder node; its default)."""

UNRECORDED = frozenset({"/rosout", "/parameter_events", "/diagnostics"})
"""Topics :func:`recorder_subscribes` leaves out when given a node's own publishers."""

_PARAM_TYPES = {
    bool: ParameterType.PARAMETER_BOOL,
    int: ParameterType.PARAMETER_INTEGER,
    float: ParameterType.PARAMETER_DOUBLE,
    str: ParameterType.PARAMETER_STRING,
}
_ARRAY_TYPES = {
    bool: Parameter.Type.BOOL_ARRAY,
    int: Parameter.Type.INTEGER_ARRAY,
    float: Parameter.Type.DOUBLE_ARRAY,
    str: Parameter.Type.STRING_ARRAY,
}


def _descriptor(name: str, default: Any, spec) -> ParameterDescriptor:
    d = ParameterDescriptor(name=name, description=spec.description, read_only=spec.read_only)
    if isinstance(default, tuple):
        kind = type(default[0]) if default else str
        d.type = _ARRAY_TYPES[kind].value
    else:
        d.type = _PARAM_TYPES[type(default)]
    if type(default) is int and (spec.low is not None or spec.high is not None):
        d.integer_range = [
            IntegerRange(
                from_value=int(spec.low if spec.low is not None else -(2**63)),
                to_value=int(spec.high if spec.high is not None else 2**63 - 1),
                step=0,
            )
        ]
    elif type(default) is float and (spec.low is not None or spec.high is not None):
        d.floating_point_range = [
            FloatingPointRange(
                from_value=float(spec.low if spec.low is not None else -1e308),
                to_value=float(spec.high if spec.high is not None else 1e308),
                step=0.0,
            )
        ]
    if spec.choices:
        d.additional_constraints = "one of: " + ", ".join(map(str, spec.choices))
    return d


def _range_error(node: str, name: str, spec, text: str) -> ParameterError:
    """Rclpy's out-of-range refusal as one of ours (``node: name = value: must be ...``)."""
    match = re.search(r"value \((.*?)\)", text)
    shown: object = match.group(1) if match else ""
    try:
        value = float(shown)
        shown = int(value) if value.is_integer() else value
    except (TypeError, ValueError):
        value = None
    if value is not None and spec.low is not None and value < spec.low:
        return ParameterError(node, name, shown, f"must be >= {spec.low}")
    if value is not None and spec.high is not None and value > spec.high:
        return ParameterError(node, name, shown, f"must be <= {spec.high}")
    return ParameterError(node, name, shown, "out of range")


def _type_error(node: str, name: str, text: str) -> ParameterError:
    """Rclpy's wrong-type refusal as one of ours (``... = '10': expected DOUBLE ...``)."""
    match = re.search(r"to '(.*?)' of type '(\w+)', expecting type '(\w+)'", text)
    if match is None:
        return ParameterError(node, name, "", text)
    value, got, want = match.groups()
    hint = f" (write {value}.0)" if want == "DOUBLE" and got == "INTEGER" else ""
    return ParameterError(node, name, value, f"expected {want}, got {got}{hint}")


def declare_params(
    node: Node,
    cls: type[P],
    on_change: Callable[[P], None] | None = None,
    prefix: str = "",
) -> P:
    """Declare every field of the parameter dataclass ``cls`` on ``node``; return the values.

    Each field becomes a parameter with a ``ParameterDescriptor`` (type, range, read-only,
    description). Values from the command line or a YAML file are checked by
    :func:`excavation_common.params.validate`. Later ``set_parameters`` calls are checked
    the same way and either applied (``on_change`` gets the new dataclass) or rejected
    with the reason; read-only parameters are always rejected.

    Raises:
        ParameterError: A value at start has the wrong type or is out of range.
    """
    values = {}
    name_of_node = node.get_fully_qualified_name()
    for f_name, spec in specs(cls).items():
        default = cls.__dataclass_fields__[f_name].default
        descriptor = _descriptor(prefix + f_name, default, spec)
        initial: Any = default
        if isinstance(default, tuple):
            initial = list(default) if default else _ARRAY_TYPES[str]
        try:
            value = node.declare_parameter(prefix + f_name, initial, descriptor).value
        except InvalidParameterValueException as exc:
            raise _range_error(name_of_node, prefix + f_name, spec, str(exc)) from None
        except InvalidParameterTypeException as exc:
            raise _type_error(name_of_node, prefix + f_name, str(exc)) from None
        except ParameterUninitializedException:
            value = ()
        values[f_name] = tuple(value) if isinstance(value, list | tuple) else value
    current = validate(cls, values, name_of_node)
    holder = {"params": current}

    def check(parameters: list[Parameter]) -> SetParametersResult:
        changes = {p.name[len(prefix) :]: p.value for p in parameters if p.name.startswith(prefix)}
        changes = {k: v for k, v in changes.items() if k in values}
        if not changes:
            return SetParametersResult(successful=True)
        try:
            new = replace_params(holder["params"], changes, name_of_node)
        except ParameterError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        if on_change is None:
            return SetParametersResult(
                successful=False, reason=f"{name_of_node}: parameters are read at start only"
            )
        holder["params"] = new
        on_change(new)
        return SetParametersResult(successful=True)

    node.add_on_set_parameters_callback(check)
    return current


def init_rclpy(**kwargs: Any) -> None:
    """``rclpy.init(**kwargs)`` with the suite's middleware settings.

    Every process of the suite initialises ROS through this: it first points Fast DDS at
    the suite's profiles (:func:`excavation_common.middleware.use_profiles`), which must
    happen before the process's first participant.
    """
    use_profiles()
    rclpy.init(**kwargs)


def spin_node(
    make_node: Callable[[], Node],
    args: list[str] | None = None,
    until: Callable[[Node], bool] | None = None,
) -> int:
    """Init rclpy, build the node, spin until shutdown (or ``until(node)``), clean up.

    Ctrl-C and external shutdown end it quietly; returns the exit code 0. A
    :class:`~excavation_common.errors.FieldError` while building the node (a bad parameter,
    an unreadable input file) is printed as one line on stderr and gives exit code 2.
    """
    init_rclpy(args=args)
    try:
        node = make_node()
    except FieldError as exc:
        print(f"error: {exc}", file=sys.stderr)
        rclpy.try_shutdown()
        return 2
    try:
        if until is None:
            rclpy.spin(node)
        else:
            while rclpy.ok() and not until(node):
                rclpy.spin_once(node, timeout_sec=0.1)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


def recorder_subscribes(node: Node, topics) -> bool:
    """Whether the bag recorder (node :data:`RECORDER_NODE`) subscribes every one of ``topics``.

    The recorder subscribes a topic only once it has seen it on the graph, so a message sent
    before that is missing from the bag (seen: a recorded trial's bag lacked tick 0). A
    node that must not send its first tick before the recorder hears it polls this.

    Args:
        node: Any node on the graph (it only asks the graph).
        topics: Topic names; :data:`UNRECORDED` ones are skipped.
    """
    return all(
        any(i.node_name == RECORDER_NODE for i in node.get_subscriptions_info_by_topic(t))
        for t in set(topics) - UNRECORDED
    )


def endpoint_name(info) -> str:
    """The fully qualified name of the node behind a graph endpoint (``/robot_0/controller``)."""
    return f"{info.node_namespace.rstrip('/')}/{info.node_name}"


def publishers_of(node: Node, topic: str) -> set[str]:
    """Fully qualified names of the nodes that publish ``topic`` (as ``node``'s graph sees it)."""
    return {endpoint_name(i) for i in node.get_publishers_info_by_topic(topic)}


def reaches(node: Node, publisher, readers=()) -> bool:
    """Whether a message ``publisher`` sends now reaches every subscription it will ever reach.

    A reliable, volatile writer delivers only to the readers it has matched when it writes;
    a reader matched later never gets that message (it is not kept for it). A node that
    publishes something only once (the lockstep simulator's tick 0, a relay's tick) must
    wait until its writer has matched every subscription the graph shows on the topic, and
    the graph shows one of each node in ``readers`` (fully qualified names). Seen: a
    controller whose blade driver's joint state of tick 0 went out before the two had
    matched waited for it until tick 1, and its robot idled tick 0.

    A subscription whose QoS cannot match the writer's keeps this false: the caller says
    what it waits for.
    """
    subscriptions = node.get_subscriptions_info_by_topic(publisher.topic_name)
    present = {endpoint_name(i) for i in subscriptions}
    return set(readers) <= present and publisher.get_subscription_count() >= len(subscriptions)


def diagnostics(
    node: Node,
    level: bytes,
    message: str,
    values: dict[str, object] | None = None,
    hardware_id: str = "",
) -> DiagnosticArray:
    """One ``/diagnostics`` array holding a single status named after ``node``.

    Args:
        node: The reporting node (its fully qualified name names the status).
        level: ``DiagnosticStatus.OK``, ``WARN``, ``ERROR`` or ``STALE``.
        message: What the node is doing, or what is wrong.
        values: Key/value details (converted with ``str``).
        hardware_id: The device behind the node, if any.
    """
    status = DiagnosticStatus(
        level=level,
        name=node.get_fully_qualified_name(),
        message=message,
        hardware_id=hardware_id,
        values=[KeyValue(key=k, value=str(v)) for k, v in (values or {}).items()],
    )
    msg = DiagnosticArray(status=[status])
    msg.header.stamp = node.get_clock().now().to_msg()
    return msg
