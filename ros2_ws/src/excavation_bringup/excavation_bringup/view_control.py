"""The live view as a console: Foxglove's service calls and client publishing, bridged to ROS.

``ant-view`` advertises the ``Services`` and ``ClientPublish`` capabilities (JSON), so that
Foxglove's own panels act on the team:

=================================  ===============================  ==========================
Foxglove                           request / message (JSON)         becomes
=================================  ===============================  ==========================
service ``/operator/estop``        ``{}`` (``{"token": ...}``)      the supervisor's ``~/estop``
``/operator/reset``, ``arm``,      the same                         ``~/reset``, ``~/arm``,
``pause``, ``resume``                                               ``~/pause``, ``~/resume``
``/operator/robot_K/enable``       ``{"data": true|false}``         ``/robot_K/enable``
publish ``/robot_K/drive/override``  geometry_msgs/Twist             ``/robot_K/drive/override``
(the Teleop panel)                 (``linear.x``, ``angular.z``)    (TwistStamped)
publish ``/robot_K/blade/commands``  ``{"data": [metres]}``          ``/robot_K/blade/commands``
=================================  ===============================  ==========================

Every service answers ``{"success": bool, "message": str}`` (the supervisor's answer, or why
the view refused). Each control action is logged with its origin (``view client N``) on
the view's log and in its ``/diagnostics`` (``controls``, ``last_control``).

**Who may act** (:class:`ControlPolicy`): on loopback (the default bind) anyone who reaches
the port does. Bound to another address (a dome network), an e-stop is always accepted, but
every other service needs the operator's token (``ant-view --operator-token``, given as
``"token"`` in the request) and client publishing (driving a robot, its blade) is refused:
a Teleop panel cannot send a token. The gates behind (the supervisor's state, each node's
motion gate) still decide whether anything moves.
"""

from __future__ import annotations

import json
import math
import re
import threading
from dataclasses import dataclass

TRIGGERS = ("estop", "reset", "arm", "pause", "resume")
"""The supervisor's services the view offers as ``/operator/NAME``."""
ANSWER_WITHIN = 5.0
"""Seconds a service call waits for the ROS side's answer."""
LOOPBACK = ("127.0.0.1", "localhost", "::1")

REQUEST_SCHEMA = {
    "type": "object",
    "properties": {"token": {"type": "string", "description": "the operator's token"}},
}
ENABLE_SCHEMA = {
    "type": "object",
    "properties": {
        "data": {"type": "boolean", "description": "true: enable, false: disable"},
        "token": {"type": "string", "description": "the operator's token"},
    },
    "required": ["data"],
}
ANSWER_SCHEMA = {
    "type": "object",
    "properties": {"success": {"type": "boolean"}, "message": {"type": "string"}},
}
_TOPIC = re.compile(r"^/robot_(\d+)/(drive/override|blade/commands)$")


class ControlError(ValueError):
    """A request or message the view cannot act on (the reason goes back to the client)."""


@dataclass(frozen=True)
class ControlPolicy:
    """Who may act through the view (module docstring).

    Attributes:
        host: The address the view serves on.
        token: The operator's token (``None``: none set).
    """

    host: str
    token: str | None = None

    @property
    def loopback(self) -> bool:
        """The view serves this machine only."""
        return self.host in LOOPBACK

    def refusal(self, action: str, request: dict) -> str | None:
        """Why ``action`` with ``request`` is refused (``None``: allowed)."""
        if action == "estop" or self.loopback:
            return None
        if self.token is None:
            return (
                f"the view serves {self.host}: control from other hosts needs ant-view "
                "--operator-token (an e-stop is always accepted)"
            )
        if request.get("token") != self.token:
            return "wrong or missing operator token"
        return None

    def publish_refusal(self) -> str | None:
        """Why client publishing (teleoperation) is refused (``None``: allowed)."""
        if self.loopback:
            return None
        return f"the view serves {self.host}: driving a robot is served on loopback only"


def parse_request(payload: bytes) -> dict:
    """A JSON object request (empty payload: ``{}``).

    Raises:
        ControlError: Not a JSON object.
    """
    if not payload.strip():
        return {}
    try:
        data = json.loads(payload)
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ControlError(f"request is not JSON: {exc}") from None
    if not isinstance(data, dict):
        raise ControlError(f"request must be a JSON object, got {type(data).__name__}")
    return data


def robot_topic(topic: str, robots: int) -> tuple[int, str]:
    """``(k, "drive/override" | "blade/commands")`` of a topic a client may publish on.

    Raises:
        ControlError: Any other topic, or no robot k.
    """
    m = _TOPIC.match(topic)
    if m is None:
        raise ControlError(
            f"{topic}: the view takes /robot_K/drive/override and /robot_K/blade/commands"
        )
    k = int(m[1])
    if k >= robots:
        raise ControlError(f"{topic}: no robot {k} (the team has {robots})")
    return k, m[2]


def _number(value, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise ControlError(f"{what} must be a finite number, got {value!r}")
    return float(value)


def twist_of(data: dict) -> tuple[float, float]:
    """``(vx, wz)`` of a geometry_msgs/Twist as JSON (missing fields: 0).

    Raises:
        ControlError: A value that is not a finite number.
    """
    linear, angular = data.get("linear") or {}, data.get("angular") or {}
    if not isinstance(linear, dict) or not isinstance(angular, dict):
        raise ControlError("linear and angular must be objects")
    return _number(linear.get("x", 0.0), "linear.x"), _number(angular.get("z", 0.0), "angular.z")


def blade_of(data: dict) -> float:
    """The set-point (m) of a std_msgs/Float64MultiArray as JSON (one value).

    Raises:
        ControlError: Not one finite number in ``data``.
    """
    values = data.get("data")
    if not isinstance(values, list) or len(values) != 1:
        raise ControlError(f"data must hold one value, got {values!r}")
    return _number(values[0], "data[0]")


def _origin(request) -> str:
    """Who sent a service request (the log's origin)."""
    return f"view client {request.client_id}"


def answer(success: bool, message: str) -> bytes:
    """A service's JSON answer."""
    return json.dumps({"success": bool(success), "message": message}).encode()


class ViewControl:
    """The ROS side of the console: clients, publishers and the Foxglove hooks, on a node.

    Args:
        node: The view's node (spun by its executor: service answers arrive there).
        robots: Robots in the team.
        policy: Who may act.
        supervisor: The supervisor node's name.
    """

    def __init__(self, node, robots: int, policy: ControlPolicy, supervisor: str = "/supervisor"):
        from geometry_msgs.msg import TwistStamped
        from std_msgs.msg import Float64MultiArray
        from std_srvs.srv import SetBool, Trigger

        self.node, self.robots, self.policy = node, robots, policy
        name = "/" + supervisor.strip("/")
        self.triggers = {t: node.create_client(Trigger, f"{name}/{t}") for t in TRIGGERS}
        self.enables = [node.create_client(SetBool, f"/robot_{k}/enable") for k in range(robots)]
        self.drives = [
            node.create_publisher(TwistStamped, f"/robot_{k}/drive/override", 10)
            for k in range(robots)
        ]
        self.blades = [
            node.create_publisher(Float64MultiArray, f"/robot_{k}/blade/commands", 10)
            for k in range(robots)
        ]
        self.channels: dict[tuple[int, int], tuple[int, str]] = {}
        self.count = 0
        self.last = ""
        self._lock = threading.Lock()

    # --- Foxglove services ------------------------------------------------------------------

    def services(self) -> list:
        """The ``foxglove.Service`` list the server advertises."""
        import foxglove

        def schema(name: str, request: dict):
            def msg(title: str, body: dict):
                return foxglove.MessageSchema(
                    encoding="json",
                    schema=foxglove.Schema(
                        name=title, encoding="jsonschema", data=json.dumps(body).encode()
                    ),
                )

            return foxglove.ServiceSchema(
                name=name, request=msg(f"{name}.Request", request),
                response=msg(f"{name}.Response", ANSWER_SCHEMA),
            )  # fmt: skip

        out = [
            foxglove.Service(
                f"/operator/{t}",
                schema=schema(f"ant_view/{t}", REQUEST_SCHEMA),
                handler=lambda req, t=t: self.call_trigger(t, req.payload, _origin(req)),
            )
            for t in TRIGGERS
        ]
        out += [
            foxglove.Service(
                f"/operator/robot_{k}/enable",
                schema=schema("ant_view/enable", ENABLE_SCHEMA),
                handler=lambda req, k=k: self.call_enable(k, req.payload, _origin(req)),
            )
            for k in range(self.robots)
        ]
        return out

    def call_trigger(self, name: str, payload: bytes, origin: str) -> bytes:
        """``/operator/NAME``: the supervisor's ``~/NAME``, if the policy allows it."""
        from std_srvs.srv import Trigger

        try:
            request = parse_request(payload)
        except ControlError as exc:
            return self._logged(name, origin, False, str(exc))
        refused = self.policy.refusal(name, request)
        if refused is not None:
            return self._logged(name, origin, False, f"refused: {refused}")
        return self._call(self.triggers[name], Trigger.Request(), name, origin)

    def call_enable(self, robot: int, payload: bytes, origin: str) -> bytes:
        """``/operator/robot_K/enable``: ``/robot_K/enable``, if the policy allows it."""
        from std_srvs.srv import SetBool

        what = f"robot {robot} enable"
        try:
            request = parse_request(payload)
            on = request.get("data")
            if not isinstance(on, bool):
                raise ControlError(f"data must be true or false, got {on!r}")
        except ControlError as exc:
            return self._logged(what, origin, False, str(exc))
        what = f"{'enable' if on else 'disable'} robot {robot}"
        refused = self.policy.refusal("enable", request)
        if refused is not None:
            return self._logged(what, origin, False, f"refused: {refused}")
        return self._call(self.enables[robot], SetBool.Request(data=on), what, origin)

    def _call(self, client, request, what: str, origin: str) -> bytes:
        if not client.service_is_ready():
            return self._logged(what, origin, False, f"no node serves {client.srv_name}")
        done = threading.Event()
        future = client.call_async(request)
        future.add_done_callback(lambda _: done.set())
        if not done.wait(ANSWER_WITHIN):
            return self._logged(what, origin, False, f"{client.srv_name}: no answer")
        reply = future.result()
        return self._logged(what, origin, bool(reply.success), str(reply.message))

    def _logged(self, what: str, origin: str, success: bool, message: str) -> bytes:
        line = f"{what} from {origin}: {'done' if success else 'not done'}: {message}"
        with self._lock:
            self.count += 1
            self.last = line
        if success:  # one call site per severity (rclpy's rule)
            self.node.get_logger().info(line)
        else:
            self.node.get_logger().warning(line)
        return answer(success, message)

    # --- client publishing ------------------------------------------------------------------

    def listener(self):
        """The ``foxglove.ServerListener`` that takes the clients' channels and messages."""
        import foxglove

        control = self

        class Listener(foxglove.ServerListener):
            def on_client_advertise(self, client, channel) -> None:
                control.advertise(client.id, channel.id, channel.topic)

            def on_client_unadvertise(self, client, client_channel_id: int) -> None:
                control.channels.pop((client.id, client_channel_id), None)

            def on_message_data(self, client, client_channel_id: int, data: bytes) -> None:
                control.message(client.id, client_channel_id, data)

        return Listener()

    def advertise(self, client: int, channel: int, topic: str) -> None:
        """A client's channel: kept when it is a robot's override topic (else logged)."""
        try:
            self.channels[(client, channel)] = robot_topic(topic, self.robots)
        except ControlError as exc:
            self.node.get_logger().warning(f"view client {client}: {exc}")

    def message(self, client: int, channel: int, data: bytes) -> None:
        """A client's message: the robot's override, if the policy allows it."""
        from geometry_msgs.msg import TwistStamped
        from std_msgs.msg import Float64MultiArray

        target = self.channels.get((client, channel))
        if target is None:
            return
        k, kind = target
        origin = f"view client {client}"
        refused = self.policy.publish_refusal()
        try:
            if refused is not None:
                raise ControlError(refused)
            request = parse_request(data)
            if kind == "drive/override":
                vx, wz = twist_of(request)
                msg = TwistStamped()
                msg.header.stamp = self.node.get_clock().now().to_msg()
                msg.header.frame_id = f"robot_{k}/base_link"
                msg.twist.linear.x, msg.twist.angular.z = vx, wz
                self.drives[k].publish(msg)
                what = f"robot {k} drive {vx:g} m/s {wz:g} rad/s"
            else:
                position = blade_of(request)
                self.blades[k].publish(Float64MultiArray(data=[position]))
                what = f"robot {k} blade {position:g} m"
        except ControlError as exc:
            self.node.get_logger().warning(
                f"/robot_{k}/{kind} from {origin}: {exc}", throttle_duration_sec=5.0
            )
            return
        with self._lock:
            self.count += 1
            self.last = f"{what} from {origin}"

    def diagnostic_values(self) -> dict:
        """The view's control counters on ``/diagnostics``."""
        with self._lock:
            return {"controls": self.count, "last_control": self.last}
