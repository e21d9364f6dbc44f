"""``team_tick``: the team tick as a ROS node (pure logic: :mod:`team_tick.core`).

Reads, per robot k: ``/robot_k/pose`` (the localiser's, or the simulator's truth),
``/robot_k/{blade_in}`` (JointState: the measured blade; ``blade/plant_state`` from
``dynamics``), ``/robot_k/behaviour`` (the controller's word), ``/robot_k/drive/operator``
(the ticks the operator's override drove the robot are in the summary's
``operator_ticks``); ``/worksite/height_map`` (the mapper's, or the simulator's); the
supervisor's ``/team/heartbeat``, ``/team/estop`` and ``/robot_k/enabled``: the tick runs
only while the team is armed (a heartbeat saying ``armed`` younger than the 0.5 s deadman,
no e-stop), and a robot disabled or lost is absent (:class:`~team_tick.core.TeamTick`).

With ``wait_for_ready`` (set by every trial and dome table) tick 0 also waits for every
controller's latched ``/robot_k/ready`` (std_msgs/Bool: its inputs are connected); with
``wait_for_recorder`` (set by recording trials and ``ant-dome up --record``) also until the
bag recorder subscribes every topic this node sends.

Publishes for each tick t, stamped ``t * tick_period``: ``{output_prefix}/robot_k/pose``,
``{output_prefix}/robot_k/stuck`` (U1: the executor aborted), ``{output_prefix}/worksite/
height_map`` (latched) and ``/robot_k/{blade_out}`` (the blade driver's ``servo_state``), so
that a controller run with ``lockstep: true`` and remapped onto ``{output_prefix}`` decides
once per tick, unchanged; ``/team/tick`` (excavation_interfaces/Tick: its stamp and number);
when robot k may move, the goal of the drive action ``/robot_k/drive``
(excavation_interfaces/action/Drive, this node its client; the goal an
``excavation_interfaces/DriveGoal``, :mod:`drive_executor.goals`), whose result (U1:
``stuck``; a rejected goal is stuck) ends the robot's motion for the tick;
``/team/snapshot`` (excavation_interfaces/Snapshot: ``stamp`` = the earliest time the
snapshot may be taken, ``settle`` after the motion ended, and the tick) to ask for a
snapshot; ``/diagnostics``. With ``snapshot_ack`` it reads ``/team/snapshot_ack`` (Snapshot,
latched: the simulator's ``dynamics`` took the snapshot of that tick at ``stamp``) and sends
a request again only while it is not acknowledged.

A robot whose executor is replaced while its goal runs (a new writer on its
``drive/status``: the old one crashed and ``ant-dome`` restarted it) is done for the tick
and stuck at once (:meth:`~team_tick.core.TeamTick.executor_restarted`): the new executor
never heard that goal, and the tick would otherwise wait ``motion_limit`` (120 s) for it.

With ``result_file`` set, the node writes :meth:`TeamTick.summary` (and its reports) there
when the last tick ends, then exits (``ant-trial --drive continuous --processes``, ``ant-dome
up --sim``).
"""

from __future__ import annotations

import json
import sys
import time
from dataclasses import dataclass
from typing import assert_never

import numpy as np
from builtin_interfaces.msg import Time as TimeMsg
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from excavation_interfaces.action import Drive
from excavation_interfaces.msg import Snapshot as SnapshotMsg
from excavation_interfaces.msg import TeamState, Tick
from geometry_msgs.msg import PoseWithCovarianceStamped
from rclpy.action import ActionClient
from rclpy.node import Node
from rclpy.task import Future
from sensor_msgs.msg import Image, JointState
from std_msgs.msg import Bool, UInt16

from blueprint_server.blueprint import resolve_blueprint
from drive_executor.errors import GoalError
from drive_executor.goals import TERMINAL, DriveGoal, goal_message
from excavation_common.constants import BladeGeometry
from excavation_common.files import write_text_atomic
from excavation_common.messages import MessageError, blade_from_joint, pose_to_grid
from excavation_common.params import param
from excavation_common.ros import (
    LATCHED,
    declare_params,
    diagnostics,
    publishers_of,
    reaches,
    recorder_subscribes,
    spin_node,
)
from excavation_common.safety import ENABLED_TOPIC, ESTOP_TOPIC, HEARTBEAT_TOPIC, MotionGate
from excavation_sim.world import scenario_start
from team_tick.core import (
    Finished,
    Phase,
    PublishTick,
    Report,
    RequestSnapshot,
    SendGoal,
    Snapshot,
    TeamTick,
    TeamTickParams,
    TickAction,
)

TICK_TOPIC = "/team/tick"
"""Each tick's number and stamp as it begins (excavation_interfaces/Tick)."""
SNAPSHOT_TOPIC = "/team/snapshot"
"""The team tick asks the simulator for a tick's snapshot (excavation_interfaces/Snapshot)."""
SNAPSHOT_ACK_TOPIC = "/team/snapshot_ack"
"""Latched: the simulator acknowledges the snapshot request it took (``dynamics``)."""
EXECUTOR_CHECK_PERIOD = 0.5
"""Wall seconds between looks at the graph for a restarted executor."""


@dataclass(frozen=True)
class TeamTickNodeParams:
    """Topic names and start-up of the node (the barrier's parameters: TeamTickParams)."""

    output_prefix: str = param("/tick", "prefix of the republished tick snapshot")
    blade_in: str = param("blade/plant_state", "measured blade joint state, per robot")
    blade_out: str = param("blade/servo_state", "the blade state republished per tick")
    startup_period: float = param(0.5, "wall s the team is present before tick 0", low=0.0)
    wait_for_ready: bool = param(
        False, "tick 0 also waits for every controller's latched /robot_k/ready"
    )
    wait_for_recorder: bool = param(
        False, "tick 0 also waits until the bag recorder subscribes every topic this node sends"
    )
    diagnostics_period: float = param(1.0, "wall s between diagnostics", low=0.05)
    result_file: str = param("", "JSON written when the last tick ends: TeamTick.summary")


def _seconds(stamp) -> float:
    return stamp.sec + stamp.nanosec * 1e-9


def _time(seconds: float) -> TimeMsg:
    ns = int(round(seconds * 1e9))
    return TimeMsg(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


class TeamTickNode(Node):
    """Thin ROS plumbing around :class:`TeamTick`."""

    def __init__(self, **kwargs) -> None:
        super().__init__("team_tick", **kwargs)
        self.params = declare_params(self, TeamTickParams)
        self.topics = declare_params(self, TeamTickNodeParams)
        p, t = self.params, self.topics
        self.n = p.robots
        self.blueprint = resolve_blueprint(p.blueprint)
        _, _, rng_state = scenario_start(
            self.blueprint.shape, p.robots, p.robots, p.seed, p.scenario
        )
        self.core = TeamTick(p, np.array([rng_state], dtype=np.uint64))
        self.geometry = BladeGeometry()
        self.errors: dict[str, str] = {}
        self.ready_since: float | None = None
        self.executors_checked = 0.0
        self.executor_writers: dict[int, set[bytes]] = {}  # drive/status writers seen
        self.reports: list[str] = []
        out = t.output_prefix.rstrip("/")
        self.pose_pubs, self.stuck_pubs, self.blade_pubs = [], [], []
        self.drives: list[ActionClient] = []  # per robot: the drive action's client
        self.inputs = []  # per robot: its word
        sub = self.create_subscription
        for k in range(self.n):
            ns = f"/robot_{k}"
            self.pose_pubs.append(
                self.create_publisher(PoseWithCovarianceStamped, f"{out}{ns}/pose", 10)
            )
            self.stuck_pubs.append(self.create_publisher(Bool, f"{out}{ns}/stuck", 10))
            self.blade_pubs.append(self.create_publisher(JointState, f"{ns}/{t.blade_out}", 10))
            self.drives.append(ActionClient(self, Drive, f"{ns}/drive"))
            sub(PoseWithCovarianceStamped, f"{ns}/pose", lambda m, k=k: self.on_pose(k, m), 10)
            sub(JointState, f"{ns}/{t.blade_in}", lambda m, k=k: self.on_blade(k, m), 10)
            self.inputs.append(
                sub(UInt16, f"{ns}/behaviour", lambda m, k=k: self.core.on_word(k, m.data), 10)
            )
            sub(Bool, f"{ns}/drive/operator", lambda m, k=k: self.on_operator(k, m), LATCHED)
            sub(Bool, f"{ns}/{ENABLED_TOPIC}", lambda m, k=k: self.on_enabled(k, m), LATCHED)
        sub(Image, "/worksite/height_map", self.on_heights, LATCHED)
        sub(TeamState, HEARTBEAT_TOPIC, self.on_heartbeat, 10)
        self.team = MotionGate(active=True, enabled=True)
        sub(Bool, ESTOP_TOPIC, lambda m: self.team.on_estop(m.data), LATCHED)
        self.core.armed = False
        self.heights_pub = self.create_publisher(Image, f"{out}/worksite/height_map", LATCHED)
        self.tick_pub = self.create_publisher(Tick, TICK_TOPIC, 10)
        self.request_pub = self.create_publisher(SnapshotMsg, SNAPSHOT_TOPIC, 10)
        if p.snapshot_ack:
            sub(
                SnapshotMsg,
                SNAPSHOT_ACK_TOPIC,
                lambda m: self.core.on_ack(int(m.tick), _seconds(m.stamp)),
                LATCHED,
            )
        self.diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.ready: set[int] = set()  # robots whose controller said ready (wait_for_ready)
        if t.wait_for_ready:
            for k in range(self.n):
                sub(Bool, f"/robot_{k}/ready", lambda m, k=k: self.on_ready(k, m), LATCHED)
        self.create_timer(0.002, self.poll)
        self.create_timer(t.diagnostics_period, self.publish_diagnostics)

    # --- inputs -----------------------------------------------------------------------------

    def _decode(self, topic: str, decode):
        try:
            value = decode()
        except (MessageError, GoalError) as exc:
            self.errors[topic] = str(exc)
            return None
        self.errors.pop(topic, None)
        return value

    def on_ready(self, k: int, msg: Bool) -> None:
        """Robot k's controller has (or has lost) every input connected."""
        if msg.data:
            self.ready.add(k)
        else:
            self.ready.discard(k)

    def on_pose(self, k: int, msg: PoseWithCovarianceStamped) -> None:
        """A pose of robot k (kept with its stamp)."""
        topic = f"/robot_{k}/pose"
        grid = self._decode(topic, lambda: pose_to_grid(msg, self.blueprint.cell_size, topic))
        if grid is not None:
            self.core.on_pose(k, grid, _seconds(msg.header.stamp), msg)

    def on_blade(self, k: int, msg: JointState) -> None:
        """Robot k's measured blade."""
        topic = f"/robot_{k}/{self.topics.blade_in}"
        blade = self._decode(topic, lambda: blade_from_joint(msg, self.geometry, topic))
        if blade is not None:
            self.core.on_blade(k, blade[0], _seconds(msg.header.stamp), msg)

    def on_heights(self, msg: Image) -> None:
        """A height map."""
        self.core.on_heights(_seconds(msg.header.stamp), msg)

    def send_goal(self, k: int, goal: DriveGoal) -> None:
        """Robot k's goal of the tick, as the drive action's goal."""
        sent = self.drives[k].send_goal_async(Drive.Goal(goal=goal_message(goal)))
        sent.add_done_callback(lambda f: self.on_goal_response(k, goal.tick, f))

    def on_goal_response(self, k: int, tick: int, sent: Future) -> None:
        """The executor accepted the goal (then its result ends it) or rejected it (stuck)."""
        handle = sent.result()
        topic = f"/robot_{k}/drive"
        if handle is None or not handle.accepted:
            self.errors[topic] = f"robot {k}'s executor rejected the goal of tick {tick}"
            self.core.on_status(k, tick, True, True, self._now())
            return
        self.errors.pop(topic, None)
        handle.get_result_async().add_done_callback(lambda f: self.on_result(k, tick, f))

    def on_result(self, k: int, tick: int, done: Future) -> None:
        """Robot k's goal of ``tick`` ended: its U1 is the result's ``stuck``."""
        answer = done.result()
        if answer is None:
            return
        terminal = answer.status in TERMINAL
        self.core.on_status(k, tick, terminal, bool(answer.result.stuck), self._now())

    def on_operator(self, k: int, msg: Bool) -> None:
        """Robot k's executor: the operator's override drives it, or no longer."""
        self.core.on_operator(k, bool(msg.data))

    def on_heartbeat(self, msg: TeamState) -> None:
        """The team state: the tick runs only while armed."""
        self.team.on_heartbeat(msg.state, self._now())
        self._gate(self._now())

    def on_enabled(self, k: int, msg: Bool) -> None:
        """Robot k enabled (waited for) or disabled or lost (absent)."""
        if msg.data:
            self.core.absent.discard(k)
        else:
            self.core.absent.add(k)

    # --- the tick ---------------------------------------------------------------------------

    def _gate(self, now: float) -> None:
        """The team's gate into the tick: armed, and if not, why (a pause, a lost heartbeat)."""
        reason = self.team.reason(now)
        self.core.armed = reason is None
        self.core.hold = MotionGate.kind(reason)

    def _now(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def missing(self) -> str | None:
        """What the team still lacks before tick 0; ``None`` once it is present.

        Present: every controller, executor and blade driver is on the graph and connected.
        The answer is shown on ``/diagnostics`` while the team tick waits.

        Connected: the middleware has matched this node's word and status subscriptions with
        their publishers (a word sent before that is lost, and the robot would miss tick 0),
        and with ``wait_for_ready`` every controller has said ``ready`` (its subscriptions to
        this node's tick topics are matched: a tick-0 pose sent before that is lost, and a
        recorder subscribed to the same topic makes this node's own subscriber count say
        nothing of the controllers; seen: robot 1 missed tick 0 of a recorded process trial),
        and each tick writer has matched every reader the graph shows, the robot's own
        controller (the node that publishes ``/robot_k/behaviour``) and executor (``drive/
        status``) among them (:func:`excavation_common.ros.reaches`).
        """
        if self.topics.wait_for_ready and len(self.ready) < self.n:
            unready = [k for k in range(self.n) if k not in self.ready]
            return f"controllers of robots {unready} not ready (their inputs unconnected)"
        if self.topics.wait_for_recorder:
            topics = [p.topic_name for p in self.publishers]
            if not recorder_subscribes(self, topics):
                return "the recorder does not subscribe every tick topic yet"
        unmatched = [s.topic_name for s in self.inputs if s.get_publisher_count() == 0]
        if unmatched:
            return f"no publisher of {unmatched[0]}"
        controllers = [publishers_of(self, f"/robot_{k}/behaviour") for k in range(self.n)]
        executors = [publishers_of(self, f"/robot_{k}/drive/status") for k in range(self.n)]
        for k in range(self.n):
            if not controllers[k] or not executors[k]:
                return f"robot {k}'s controller or executor is not on the graph"
            if not self.drives[k].server_is_ready():
                return f"robot {k}'s drive action server is not ready yet"
        everyone = set().union(*controllers)
        for k in range(self.n):
            for pub, readers in (
                (self.pose_pubs[k], everyone),
                (self.stuck_pubs[k], controllers[k]),
                (self.blade_pubs[k], ()),
            ):
                if not reaches(self, pub, readers) or pub.get_subscription_count() == 0:
                    return f"{pub.topic_name} does not reach its readers yet"
        return None

    def team_present(self) -> bool:
        """Every controller, executor and blade driver of the team is on the graph and connected."""
        return self.missing() is None

    def poll(self) -> None:
        """Start the ticks once the team is present; then run the state machine."""
        now, wall = self._now(), time.monotonic()
        self._gate(now)
        if self.core.phase is Phase.WAITING:
            if not self.team_present():
                self.ready_since = None
                return
            if self.ready_since is None:
                self.ready_since = wall
            if wall - self.ready_since >= self.topics.startup_period:
                self.execute(self.core.start(now, wall))
            return
        if wall - self.executors_checked >= EXECUTOR_CHECK_PERIOD:
            self.executors_checked = wall
            for k in self.replaced_executors():
                self.execute(self.core.executor_restarted(k, now))
        self.execute(self.core.step(now, wall))

    def replaced_executors(self) -> list[int]:
        """Robots whose ``drive/status`` has a publisher the last check did not see.

        A new writer is a restarted executor (a crashed one's writer may stay on the graph
        until its lease runs out, so a count would not tell). The first check only learns.
        """
        out = []
        for k in range(self.n):
            topic = f"/robot_{k}/drive/status"
            gids = {bytes(i.endpoint_gid) for i in self.get_publishers_info_by_topic(topic)}
            known = self.executor_writers.get(k)
            if known is not None and gids - known:
                out.append(k)
            self.executor_writers[k] = gids
        return out

    def execute(self, actions: list[TickAction]) -> None:
        """Publish what the state machine decided, in its order."""
        for action in actions:
            match action:
                case RequestSnapshot(tick, not_before):
                    self.request_pub.publish(SnapshotMsg(stamp=_time(not_before), tick=tick))
                case PublishTick(tick, stamp, snapshot):
                    self.publish_tick(tick, _time(stamp), snapshot)
                case SendGoal(k, tick, stamp, word, turn):
                    ns = int(round(stamp * 1e9))
                    sec_ns = (ns // 1_000_000_000, ns % 1_000_000_000)
                    self.send_goal(k, DriveGoal(tick, word, turn, k, sec_ns))
                case Report(message):
                    self.reports.append(message)
                    self.get_logger().warning(message)
                    self.publish_diagnostics(message)
                case Finished():
                    if self.topics.result_file:
                        summary = self.core.summary().to_json() | {"reports": self.reports}
                        write_text_atomic(self.topics.result_file, json.dumps(summary))
                    self.publish_diagnostics(f"finished {self.core.tick} ticks")
                case _:
                    assert_never(action)

    def publish_tick(self, tick: int, stamp: TimeMsg, snapshot: Snapshot) -> None:
        """Republish a snapshot stamped with its tick."""
        self.tick_pub.publish(Tick(stamp=stamp, tick=tick))
        heights = snapshot.heights
        heights.header.stamp = stamp
        self.heights_pub.publish(heights)
        for k in range(self.n):
            self.stuck_pubs[k].publish(Bool(data=bool(snapshot.stuck[k])))
            blade = snapshot.blades[k]
            blade.header.stamp = stamp
            self.blade_pubs[k].publish(blade)
            pose = snapshot.poses[k]
            pose.header.stamp = stamp
            self.pose_pubs[k].publish(pose)

    def publish_diagnostics(self, message: str | None = None) -> None:
        """The tick, its phase, robots left out."""
        late = sum(self.core.late)
        level = DiagnosticStatus.WARN if (late or self.errors) else DiagnosticStatus.OK
        text = message or f"tick {self.core.tick}: {self.core.phase.value}"
        if message is None and self.core.phase is Phase.WAITING:
            reason = self.missing()
            text += f" ({reason})" if reason else ""
        if self.errors:
            text += "; " + "; ".join(self.errors.values())
        self.diag_pub.publish(
            diagnostics(
                self,
                level,
                text,
                {"tick": self.core.tick, "phase": self.core.phase.value, "robots_late": late},
            )
        )


def main(args: list[str] | None = None) -> int:
    """Entry point of ``team_tick`` (ends after ``steps`` ticks)."""
    return spin_node(TeamTickNode, args, until=lambda node: node.core.phase is Phase.FINISHED)


if __name__ == "__main__":
    sys.exit(main())
