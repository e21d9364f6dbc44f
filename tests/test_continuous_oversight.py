"""Operator oversight of a running 4-robot continuous trial (executors, team tick, ``dynamics``).

The trial (``ant-trial --drive continuous``, composed) runs in a process of its own, so that
the watcher here does not take its interpreter; the test is the operator: a node on the
trial's domain that records the executors' ``cmd_vel``, the blade set-points, the team
tick, the heartbeat and the supervisor's diagnostics, and calls the supervisor's services
(or ``ant-operator`` as a separate process). Every assertion is on sim time (message stamps)
or message content; wall-time latencies are printed, never asserted (docs/benchmarks.md,
"Oversight").

Each test runs the trial in a process of its own (and some start the supervisor or
``ant-operator`` as processes too), so the module is part of ``make test-system``; the safety
rules each of these exercises have their node-level tests in ``make test``
(tests/test_executor_node.py, tests/test_blade_safety.py, tests/test_supervisor_node.py) and
the lockstep flow its composed one (tests/test_trial_oversight.py).
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from helpers.diagnostics import DiagnosticsProbe
from helpers.trials import GENOME, ROBOTS, offline_trace
from helpers.watchers import OperatorWatcher, occlude

from excavation_bringup.deployment import Deployment
from excavation_bringup.nodes import LOST_GRACE, LOST_TIMEOUT
from excavation_common.safety import ESTOPPED

SEED = 3
pytestmark = pytest.mark.system

STOP_LIMIT = 0.1 + 1e-9
"""Sim seconds from an e-stop or pause to zero ``cmd_vel`` from every executor: 100 ms, two
steps (stamps are float seconds here: a stop two steps after a pause at 39.25 s measured
39.35 - 39.25 = 0.10000000000000142 and failed a bare 0.1)."""
DEADMAN = 0.5
STEP = 0.05
"""The simulator's step: an executor answers each pose, so a stop shows one step later."""
TIME_FACTOR = 5.0
"""Sim time at most 5 x real time (unlimited, the trial runs some 40 x here): the watcher
then keeps up with every ``cmd_vel`` (4 robots x 20 Hz of sim time) on a loaded machine."""


def _trial(spec: Deployment, out) -> None:
    """The trial process: runs the continuous trial and sends back its result (or error)."""
    from excavation_bringup.trial import run_deployment

    try:
        out.put(("result", run_deployment(spec)))
    except Exception as exc:  # reported by the test
        out.put(("error", repr(exc)))


class Trial:
    """A continuous trial in a spawned process."""

    def __init__(self, domain: int, steps: int, exact=True, time_factor=TIME_FACTOR, **spec):
        self.spec = Deployment(
            controller=GENOME,
            robots=ROBOTS,
            steps=steps,
            seed=SEED,
            blueprint="default:1",
            scenario=0,
            domain=domain,
            command_timeout=spec.pop("command_timeout", 30.0),
            timeout=spec.pop("timeout", 600.0),
            blade_driver=True,
            record=None,
            perception=spec.pop("perception", "truth"),
            drive="continuous",
            exact=exact,
            time_factor=time_factor,
            **spec,
        )
        ctx = multiprocessing.get_context("spawn")
        self.queue = ctx.Queue()
        self.process = ctx.Process(target=_trial, args=(self.spec, self.queue), daemon=True)
        self.process.start()
        self.outcome = None

    def done(self) -> bool:
        if self.outcome is None and not self.queue.empty():
            self.outcome = self.queue.get()
        return self.outcome is not None or not self.process.is_alive()

    def result(self):
        assert self.outcome is not None, f"trial process ended with {self.process.exitcode}"
        kind, value = self.outcome
        assert kind == "result", value
        self.process.join(timeout=30)
        return value

    def stop(self):
        if self.process.is_alive():
            self.process.terminate()
            self.process.join(timeout=30)
        if self.process.is_alive():
            self.process.kill()
            self.process.join(timeout=30)


class Watcher(OperatorWatcher):
    """The operator's side (:class:`helpers.watchers.OperatorWatcher`, plus the continuous
    topics)."""

    def __init__(self, domain: int):
        from excavation_interfaces.msg import DriveStatus, TeamState, Tick
        from geometry_msgs.msg import TwistStamped

        super().__init__(domain, ROBOTS)  # servo set-points, enables; ``tick`` is /clock's
        self.team_tick = -1
        self.heartbeats: list[tuple[float, float, str]] = []  # (wall, stamp, state)
        self.cmd = {k: [] for k in range(ROBOTS)}  # (wall, stamp, vx, wz)
        self.goals = {k: [] for k in range(ROBOTS)}  # wall
        self.poses: list[tuple[float, float, float, float]] = []  # robot 0: (stamp, x, y, yaw)
        sub = self.node.create_subscription

        def stamp(header) -> float:
            return header.stamp.sec + header.stamp.nanosec * 1e-9

        def on_tick(msg):
            self.team_tick = int(msg.tick)

        sub(Tick, "/team/tick", on_tick, 10)
        sub(
            TeamState,
            "/team/heartbeat",
            lambda m: self.heartbeats.append((time.monotonic(), stamp(m), m.state)),
            50,
        )
        self.diagnostics = DiagnosticsProbe(self.node)
        for k in range(ROBOTS):
            ns = f"/robot_{k}"
            sub(
                TwistStamped,
                f"{ns}/cmd_vel",
                lambda m, k=k: self.cmd[k].append(
                    (time.monotonic(), stamp(m.header), m.twist.linear.x, m.twist.angular.z)
                ),
                200,
            )
            sub(  # every goal the executor starts (the drive action's, EXECUTING)
                DriveStatus,
                f"{ns}/drive/status",
                lambda m, k=k: (
                    self.goals[k].append(time.monotonic())
                    if m.status == DriveStatus.STATUS_EXECUTING
                    else None
                ),
                50,
            )

    def watch_pose(self, k: int) -> None:
        """Record robot ``k``'s per-step pose (the simulator's, 20 Hz of sim time)."""
        import math

        from geometry_msgs.msg import PoseWithCovarianceStamped

        def on_pose(m):
            q = m.pose.pose.orientation
            self.poses.append(
                (
                    m.header.stamp.sec + m.header.stamp.nanosec * 1e-9,
                    m.pose.pose.position.x,
                    m.pose.pose.position.y,
                    2 * math.atan2(q.z, q.w),
                )
            )

        self.node.create_subscription(PoseWithCovarianceStamped, f"/robot_{k}/pose", on_pose, 200)

    def sim_now(self) -> float:
        """The newest heartbeat stamp: the supervisor's sim time, to a heartbeat period."""
        return self.heartbeats[-1][1]

    def supervisor_says(self, robot: int, prefix: str, since: float = -1.0) -> float:
        """Sim stamp of the supervisor's first diagnostics after ``since`` on which robot
        ``robot``'s line starts with ``prefix``."""
        return next(
            h.stamp
            for h in self.diagnostics.heard(lambda name: name.endswith("supervisor"))
            if h.stamp > since and h.values.get(f"robot_{robot}", "").startswith(prefix)
        )

    def spin_for(self, seconds: float) -> None:
        self.spin_until(lambda: False, timeout=seconds)

    def moving(self) -> list[int]:
        """Robots whose newest ``cmd_vel`` moves them."""
        return [k for k, msgs in self.cmd.items() if msgs and (msgs[-1][2] or msgs[-1][3])]

    def heartbeat_stamp(self, state: str, since: float) -> float:
        """Sim stamp of the first heartbeat saying ``state`` that arrived after wall ``since``."""

        def first():
            return next((s for w, s, f in self.heartbeats if w >= since and f == state), None)

        assert self.spin_until(lambda: first() is not None, 60), f"no heartbeat saying {state}"
        return first()


def stops(watch: Watcher, start: float, end: float = float("inf"), robots=None) -> dict[int, float]:
    """Per robot, the sim stamp from which its ``cmd_vel`` is zero through ``end``.

    Looks at the commands stamped from ``start`` (one step before it) to ``end``: each
    robot's must end in zeros (asserted); returns the stamp of the first zero after its
    last non-zero command there (the test compares it with ``start``).
    """
    out = {}
    for k in robots if robots is not None else range(ROBOTS):
        msgs = watch.cmd[k]
        window = [(s, vx, wz) for _, s, vx, wz in msgs if start - STEP <= s <= end]
        moving = [s for s, vx, wz in window if vx or wz]
        last_move = max(moving) if moving else -np.inf
        zeros = [s for s, vx, wz in window if not (vx or wz) and s > last_move]
        assert zeros, f"robot {k}: no zero cmd_vel after {start:.3f} s"
        out[k] = min(zeros)
    return out


def intervene(watch: Watcher, tick: int, service: str, state: str, hold: float):
    """At ``tick`` with a robot driving, call ``/supervisor/SERVICE``.

    Returns the robots driving then, the wall time of the request and the sim stamp of the
    supervisor's first heartbeat saying ``state``, after ``hold`` wall seconds.
    """
    assert watch.spin_until(lambda: watch.team_tick >= tick and watch.moving(), 400)
    moving = watch.moving()
    reply, sent = watch.call(f"/supervisor/{service}")
    assert reply.success
    watch.spin_for(hold)
    return moving, sent, watch.heartbeat_stamp(state, sent - 0.5)


def test_estop_at_tick_10_stops_every_executor_within_100_ms_then_reset_and_arm_continue(domain):
    steps = 16
    watch = Watcher(domain)
    trial = Trial(domain, steps)
    try:
        moving, sent, t_estop = intervene(watch, 10, "estop", ESTOPPED, 1.0)
        held_tick = watch.team_tick
        goals_before = {k: len(g) for k, g in watch.goals.items()}
        watch.spin_for(1.0)
        assert watch.call("/supervisor/reset")[0].success
        watch.spin_for(1.0)  # reset alone: disarmed, nothing moves
        assert watch.team_tick == held_tick
        assert {k: len(g) for k, g in watch.goals.items()} == goals_before  # no goal granted
        _, armed_at = watch.call("/supervisor/arm")
        t_arm = watch.heartbeat_stamp("armed", armed_at - 0.5)
        zero = stops(watch, t_estop, t_arm)
        wall = {k: next(w for w, s, vx, wz in watch.cmd[k] if s >= zero[k]) - sent for k in zero}
        # Blades: every set-point between the e-stop and the arm is home, marked held.
        blades = {
            k: [(v, f) for w, _, v, f in watch.servo[k] if sent <= w < armed_at] for k in zero
        }
        homed = {
            k: next(w for w, _, _, h in watch.servo[k] if w >= sent and h) - sent
            for k in range(ROBOTS)
        }
        print(
            f"e-stop at tick {held_tick} (robots {moving} driving): zero cmd_vel from every "
            f"executor {1e3 * max(zero.values()) - 1e3 * t_estop:.0f} ms sim after the "
            f"e-stop heartbeat, {1e3 * max(wall.values()):.1f} ms wall after the request; "
            f"every blade home {1e3 * max(homed.values()):.1f} ms wall"
        )
        assert max(zero.values()) - t_estop <= STOP_LIMIT
        for k, sent_home in blades.items():
            assert sent_home, f"robot {k}: no blade set-point after the e-stop"
            assert all(h and v == pytest.approx(0.10) for v, h in sent_home), k
        assert watch.spin_until(trial.done, 600)
        result = trial.result()
    finally:
        trial.stop()
        watch.close()
    assert len(result.trace) == steps + 1 and sum(result.missed.values()) == 0
    assert np.array(result.commands)[held_tick + 1 :].any()  # the team carried on


def test_pause_and_resume_mid_motion_end_as_an_unpaused_trial(domain):
    steps = 14
    watch = Watcher(domain)
    trial = Trial(domain, steps)
    try:
        moving, sent, t_pause = intervene(watch, 5, "pause", "paused", 1.5)
        paused_tick = watch.team_tick
        _, resumed = watch.call("/supervisor/resume")
        t_resume = watch.heartbeat_stamp("armed", resumed - 0.5)
        assert watch.team_tick == paused_tick
        zero = stops(watch, t_pause, t_resume)
        print(
            f"pause at tick {paused_tick} (robots {moving} driving): zero cmd_vel "
            f"{1e3 * (max(zero.values()) - t_pause):.0f} ms sim later; paused "
            f"{t_resume - t_pause:.1f} s sim"
        )
        assert max(zero.values()) - t_pause <= STOP_LIMIT
        assert watch.spin_until(trial.done, 600)
        result = trial.result()
    finally:
        trial.stop()
        watch.close()
    heights, fitness, trace = offline_trace(GENOME, ROBOTS, steps, SEED)
    assert sum(result.missed.values()) == 0 and result.robots_late == 0
    assert np.array_equal(result.heights, heights) and result.fitness == fitness
    assert result.trace == trace


def test_supervisor_sigkilled_every_robot_stops_by_the_deadman(domain):
    steps = 40
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain))
    cmd = [sys.executable, "-m", "team_supervisor.supervisor_node", "--ros-args"]
    for name, value in (
        ("robots", ROBOTS),
        ("lost_timeout", LOST_TIMEOUT),
        ("lost_grace", LOST_GRACE),
        ("use_sim_time", "true"),
    ):
        cmd += ["-p", f"{name}:={value}"]
    watch = Watcher(domain)
    sup = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    # Sim time at most twice real time: the supervisor's heartbeat follows /clock from
    # another process, and the deadman counts 0.5 s of sim time.
    trial = Trial(domain, steps, time_factor=2.0, supervisor="external")
    try:
        assert watch.call("/supervisor/arm")[0].success
        assert watch.spin_until(lambda: watch.team_tick >= 4 and watch.moving(), 400)
        moving = watch.moving()
        sup.send_signal(signal.SIGKILL)
        killed = time.monotonic()
        sup.wait()
        watch.spin_for(2.0)
        t_last = watch.sim_now()  # the newest heartbeat: none comes after the kill
        held_tick = watch.team_tick
        zero = stops(watch, t_last + DEADMAN + STEP)
        wall = {k: next(w for w, s, _, _ in watch.cmd[k] if s >= zero[k]) - killed for k in zero}
        watch.spin_for(1.0)
        assert watch.team_tick == held_tick  # the team tick holds too: no new tick
        print(
            f"supervisor SIGKILLed at tick {held_tick} (robots {moving} driving): every "
            f"executor at zero {max(zero.values()) - t_last:.2f} s sim after the last "
            f"heartbeat, {max(wall.values()):.2f} s wall after the kill (sim at most 2 x real "
            f"time)"
        )
        assert max(zero.values()) <= t_last + DEADMAN + 2 * STEP
    finally:
        if sup.poll() is None:
            sup.send_signal(signal.SIGINT)
            sup.wait(timeout=10)
        trial.stop()
        watch.close()


def test_robot_hidden_from_the_camera_stops_is_disabled_and_the_others_finish(domain):
    steps, hidden = 14, 2
    watch = Watcher(domain)
    trial = Trial(domain, steps, exact=False, perception="full", timeout=900.0)
    try:
        assert watch.spin_until(lambda: watch.team_tick >= 3, 600)
        occlude(watch, "2:front,2:rear", timeout=60.0)
        hidden_at = watch.team_tick
        assert watch.spin_until(
            lambda: watch.enabled[hidden] and not watch.enabled[hidden][-1], 600
        )
        lost_at = watch.team_tick
        assert watch.spin_until(trial.done, 900)
        result = trial.result()
        watch.spin_for(0.5)
    finally:
        trial.stop()
        watch.close()
    t_lost = watch.supervisor_says(hidden, "lost")
    t_disabled = watch.supervisor_says(hidden, "disabled (lost)")
    commands = np.array(result.commands)
    others = [k for k in range(ROBOTS) if k != hidden]
    print(
        f"robot {hidden} hidden at tick {hidden_at}: lost (stopped, absent) at tick {lost_at}, "
        f"{t_lost:.1f} s sim, disabled {t_disabled - t_lost:.1f} s sim later; fitness "
        f"{result.fitness:.4f} after {steps} ticks, missed {result.missed}, "
        f"{result.seconds:.0f} s wall, {result.sim_seconds:.0f} s sim"
    )
    # It stops at once and stays stopped; later it is disabled (lost beyond the grace).
    assert stops(watch, t_lost, robots=[hidden])[hidden] <= t_lost + STOP_LIMIT
    assert t_disabled > t_lost
    assert len(result.trace) == steps + 1  # the trial ran to its end
    assert (commands[lost_at + 1 :, hidden] == 0).all()
    assert commands[lost_at + 1 :, others].any()  # the other three carry on
    assert sum(result.missed.values()) == 0 and result.robots_late == 0


def test_disable_enable_and_drive_override_through_ant_operator(domain):
    steps, robot = 30, 1
    watch = Watcher(domain)
    watch.watch_pose(0)
    trial = Trial(domain, steps, time_factor=2.0)  # ant-operator streams at 10 Hz of wall time
    try:
        assert watch.spin_until(lambda: watch.team_tick >= 2, 400)
        assert watch.operator(domain, "disable", str(robot)).returncode == 0
        off_at = watch.team_tick
        assert watch.spin_until(lambda: watch.team_tick >= off_at + 4, 400)
        assert "robot 1: disabled (operator)" in watch.operator(domain, "status").stdout
        on_at = watch.team_tick
        assert watch.operator(domain, "enable", str(robot)).returncode == 0
        first = len(watch.cmd[0])
        started = time.monotonic()
        drive = watch.operator(domain, "drive", "0", "0.5", "0.5", "--for", "2")
        assert drive.returncode == 0, drive.stderr
        t_end = watch.sim_now()  # the stream's last (zero) twist is in by now
        watch.spin_for(1.0)
        overridden = [(w, s) for w, s, vx, wz in watch.cmd[0][first:] if (vx, wz) == (0.15, 0.5)]
        assert watch.spin_until(trial.done, 600)
        result = trial.result()
    finally:
        trial.stop()
        watch.close()
    commands = np.array(result.commands)
    # Robot 1 idled while disabled (not waited for, nor missed), its wheels at zero from the
    # supervisor's change to the enable; the others carried on.
    t_off = watch.supervisor_says(robot, "disabled (operator)")
    t_on = watch.supervisor_says(robot, "enabled", since=t_off)
    off = stops(watch, t_off, t_on, robots=[robot])[robot]
    print(
        f"disable robot {robot} at tick {off_at}: zero cmd_vel {1e3 * (off - t_off):.0f} ms sim "
        f"after the supervisor's change; idle and absent until the enable at tick {on_at}"
    )
    assert off <= t_off + STOP_LIMIT
    assert (commands[off_at + 2 : on_at, robot] == 0).all()
    assert commands[off_at + 2 : on_at, [0, 2, 3]].any()
    assert commands[on_at + 2 :, robot].any()  # enabled again: it takes part
    assert sum(result.missed.values()) == 0
    # The override won while fresh, limited to the throttle-up limit (0.15 m/s of the
    # 0.5 asked), moved the robot, and ended with the operator's stream.
    assert overridden, "no cmd_vel carried the operator's (clamped) twist"
    t0, t1 = overridden[0][1], overridden[-1][1]
    during = [p for p in watch.poses if t0 <= p[0] <= t1 + STEP]
    moved = np.hypot(during[-1][1] - during[0][1], during[-1][2] - during[0][2])
    turned = abs(np.angle(np.exp(1j * (during[-1][3] - during[0][3]))))
    print(
        f"ant-operator drive 0 0.5 0.5 --for 2: {len(overridden)} cmd_vel at (0.15, 0.5) over "
        f"{t1 - t0:.1f} s sim (from {overridden[0][0] - started:.2f} s wall after the command "
        f"started); robot 0 moved {moved:.3f} m and turned {turned:.2f} rad"
    )
    assert t1 - t0 >= 1.0  # the stream kept it in charge, not one message
    assert moved > 0.02 or turned > 0.2
    assert t1 <= t_end + 0.1 + STEP  # nothing of the override after its last message


def test_a_foxglove_client_drives_robot_1_hands_it_back_and_stops_the_team(domain):
    """The live view's console side (``view_control``) on the operator's node: a client's
    Teleop twists drive robot 1 while robot 0 keeps digging; the stream stops and robot 1
    takes the team's goals again (its ticks under the operator are in the trial's result);
    then the client's e-stop stops every executor within 100 ms of sim time."""
    import foxglove
    from helpers.view_client import free_port

    from excavation_bringup.view_client import ControlClient
    from excavation_bringup.view_control import ControlPolicy, ViewControl

    steps, robot = 24, 1
    watch = Watcher(domain)
    trial = Trial(domain, steps, time_factor=2.0)  # the client streams at 10 Hz of wall time
    control = ViewControl(watch.node, ROBOTS, ControlPolicy("127.0.0.1"))
    server = foxglove.start_server(
        name="test", port=free_port(),
        capabilities=[foxglove.Capability.Services, foxglove.Capability.ClientPublish],
        supported_encodings=["json"], server_listener=control.listener(),
        services=control.services(),
    )  # fmt: skip
    client = ControlClient(server.port, pump=lambda: watch.executor.spin_once(timeout_sec=0.01))
    try:
        assert watch.spin_until(lambda: watch.team_tick >= 2, 400)
        channel = client.advertise(f"/robot_{robot}/drive/override", "geometry_msgs/Twist")
        assert client.wait(lambda: control.channels, 60)
        taken_at = watch.team_tick
        first = len(watch.cmd[robot])
        deadline = time.monotonic() + 3.0  # 3 s of wall, 6 s of sim: a few ticks
        while time.monotonic() < deadline:
            client.publish(channel, {"linear": {"x": 0.05}, "angular": {"z": 0.0}})
            client.wait(lambda: False, 0.1)
        released_at = watch.team_tick
        driven = [(s, vx) for _, s, vx, wz in watch.cmd[robot][first:] if vx == 0.05]
        assert watch.spin_until(lambda: watch.team_tick >= released_at + 3, 400)
        ok, reply = client.call("/operator/estop", {})
        assert ok and reply["success"], reply
        sent = time.monotonic()
        t_estop = watch.heartbeat_stamp(ESTOPPED, sent - 0.5)
        watch.spin_for(1.0)
        zero = stops(watch, t_estop)
        assert watch.call("/supervisor/reset")[0].success
        assert watch.call("/supervisor/arm")[0].success
        assert watch.spin_until(trial.done, 600)
        result = trial.result()
    finally:
        client.close()
        server.stop()
        trial.stop()
        watch.close()
    print(
        f"robot {robot} under the client's twists from tick {taken_at} to {released_at}: "
        f"{len(driven)} cmd_vel at 0.05 m/s; result.operator_ticks = {result.operator_ticks}; "
        f"e-stop from the client: every executor zero {1e3 * (max(zero.values()) - t_estop):.0f}"
        " ms sim after the e-stop heartbeat"
    )
    assert driven, "no cmd_vel carried the client's twist"
    assert max(zero.values()) - t_estop <= STOP_LIMIT
    commands = np.array(result.commands)
    ticks = result.operator_ticks.get(robot, [])
    assert ticks and min(ticks) >= taken_at - 1 and max(ticks) <= released_at + 1, ticks
    assert 0 not in result.operator_ticks  # robot 0 was never taken over
    assert commands[min(ticks) : max(ticks) + 1, 0].any()  # robot 0 kept digging meanwhile
    assert commands[max(ticks) + 1 :, robot].any()  # robot 1 back with the team's words
    assert sum(result.missed.values()) == 0
