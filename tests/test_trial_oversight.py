"""Operator oversight of a running lockstep trial (4 robots, blade drivers, supervisor).

The trial runs in a thread (composed nodes, its own rclpy context); the test is the
operator: a node of its own on the trial's domain that watches the tick (``/clock``) and the
blade drivers' set-points and calls the supervisor's services, and ``ant-operator`` as a
separate process. Latencies are printed (never asserted on wall time).

The e-stop / pause flow runs in ``make test``; the tests that start processes of their own
(``ant-operator``, a supervisor to SIGKILL) or run full perception are ``system`` tests
(``make test-system``).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from helpers.operator import operator
from helpers.trials import GENOME, ROBOTS, finish, offline, start_trial, stays_still
from helpers.watchers import OperatorWatcher, occlude

from excavation_bringup.nodes import LOST_GRACE, LOST_TIMEOUT


def test_estop_at_tick_10_then_pause_resume_ends_as_an_uninterrupted_trial(domain):
    steps = 30
    watch = OperatorWatcher(domain)
    try:
        thread, out = start_trial(domain, steps)
        assert watch.spin_until(lambda: watch.tick >= 10)
        reply, sent = watch.call("/supervisor/estop")
        assert reply.success
        assert watch.spin_until(lambda: len(watch.held_since(sent)) == ROBOTS, timeout=10)
        at = watch.tick
        held = watch.held_since(sent)
        stamps = {k: next(s for w, s, _, h in watch.servo[k] if w >= sent and h) for k in held}
        print(
            f"e-stop at tick {at}: every blade home within "
            f"{1e3 * (max(held.values()) - sent):.1f} ms wall, "
            f"{max(stamps.values()) - at} s sim time (stamps {sorted(set(stamps.values()))})"
        )
        assert set(stamps.values()) <= {at}  # no tick went by: 0 s of sim time
        assert stays_still(watch)  # no behaviour applied while e-stopped
        assert watch.call("/supervisor/reset")[0].success
        assert stays_still(watch)  # reset alone: disarmed, still held
        assert watch.call("/supervisor/arm")[0].success
        assert watch.spin_until(lambda: watch.tick >= 20)
        assert watch.call("/supervisor/pause")[0].success
        assert stays_still(watch)
        assert watch.call("/supervisor/resume")[0].success
        result = finish(watch, thread, out)
    finally:
        watch.close()
    heights, fitness = offline(GENOME, ROBOTS, steps, 3)
    assert sum(result.missed.values()) == 0
    assert np.array_equal(result.heights, heights) and result.fitness == fitness
    assert result.holds >= 3  # e-stop, reset (disarmed), pause


@pytest.mark.system
def test_ant_operator_disables_a_robot_and_overrides_a_blade_in_a_running_trial(domain):
    """``ant-operator`` disables robot 1, enables it again and overrides robot 0's blade.

    Each ``ant-operator`` is a new process that takes seconds to find the services on a
    loaded machine, longer than this trial needs for all its ticks: the test pauses the team
    while one starts, and lets the trial run where ticks must pass (robot 1 disabled, the
    blade override streaming).
    """
    from std_msgs.msg import Float64MultiArray

    steps = 200
    watch = OperatorWatcher(domain)
    overrides = []
    watch.node.create_subscription(
        Float64MultiArray, "/robot_0/blade/commands", lambda m: overrides.append(m.data[0]), 10
    )
    try:
        thread, out = start_trial(domain, steps)
        assert watch.spin_until(lambda: watch.tick >= 5)
        assert watch.call("/supervisor/pause")[0].success
        status = watch.operator(domain, "status")
        assert status.returncode == 0 and "team paused" in status.stdout
        disabled = watch.operator(domain, "disable", "1")
        assert disabled.returncode == 0, disabled.stderr
        off_at = watch.tick
        assert watch.call("/supervisor/resume")[0].success
        assert watch.spin_until(lambda: watch.tick >= off_at + 8)
        assert watch.call("/supervisor/pause")[0].success
        assert "robot 1: disabled (operator)" in watch.operator(domain, "status").stdout
        on_at = watch.tick
        assert watch.operator(domain, "enable", "1").returncode == 0
        done = {}
        blade = threading.Thread(
            target=lambda: done.setdefault(
                "r", operator(domain, "blade", "0", "0.05", "--for", "3", timeout="60")
            )
        )
        blade.start()
        assert watch.spin_until(lambda: bool(overrides), timeout=120)  # streaming now
        assert watch.call("/supervisor/resume")[0].success
        assert watch.spin_until(lambda: not blade.is_alive(), timeout=120)
        blade.join()
        assert done["r"].returncode == 0, done["r"].stderr
        result = finish(watch, thread, out)
    finally:
        watch.close()
    commands = np.array(result.commands)
    # Robot 1 idled while disabled (its ticks were not waited for, nor missed); the others
    # carried on.
    assert (commands[off_at + 2 : on_at - 1, 1] == 0).all()
    assert commands[off_at + 2 : on_at - 1, [0, 2, 3]].any()
    assert result.missed == {0: 0, 1: 0, 2: 0, 3: 0}
    overridden = [v for _, _, v, h in watch.servo[0] if not h and v == pytest.approx(0.05)]
    assert overridden, "the operator's blade set-point never reached the simulator"


@pytest.mark.system
def test_supervisor_sigkilled_every_blade_homes_by_deadman_then_a_new_one_resumes(domain):
    # 200 ticks: a trial of 25 could end between the tick the test sees and the deadman.
    steps = 200
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain))
    cmd = [
        sys.executable,
        "-m",
        "team_supervisor.supervisor_node",
        "--ros-args",
        "-p",
        f"robots:={ROBOTS}",
        "-p",
        f"lost_timeout:={LOST_TIMEOUT}",
        "-p",
        f"lost_grace:={LOST_GRACE}",
    ]
    watch = OperatorWatcher(domain)
    sup = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        thread, out = start_trial(domain, steps, supervisor="external")
        assert watch.spin_until(lambda: watch.tick == 0)  # tick 0 goes out unarmed...
        assert stays_still(watch) and watch.tick == 0  # ...but is not applied
        assert watch.call("/supervisor/arm")[0].success
        assert watch.spin_until(lambda: watch.tick >= 8)
        sup.send_signal(signal.SIGKILL)
        killed, killed_at = time.monotonic(), watch.tick
        sup.wait()
        # Generous: the deadman is 0.5 s; this only bounds a hang on a loaded machine.
        assert watch.spin_until(lambda: len(watch.resting_home(killed)) == ROBOTS, timeout=60)
        held = watch.resting_home(killed)
        assert stays_still(watch)  # the simulator holds too
        at = watch.tick
        stamps = {watch.servo[k][-1][1] for k in held}  # the tick each blade rests home in
        print(
            f"supervisor SIGKILLed at tick {killed_at}: every blade home within "
            f"{max(held.values()) - killed:.3f} s wall (deadman 0.5 s); lockstep sim time ran "
            f"{at - killed_at} s (ticks) meanwhile, then held at tick {at}"
        )
        assert stamps == {at}  # homed in the tick the simulator holds: none applied after
        sup = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        # A fresh supervisor starts disarmed. The killed one's service stays in the graph
        # until its lease ends, so the first request may go nowhere: arm is idempotent.
        assert watch.call("/supervisor/arm", timeout=60.0, tries=6)[0].success
        result = finish(watch, thread, out)
    finally:
        if sup.poll() is None:
            sup.send_signal(signal.SIGINT)
            sup.wait(timeout=10)
        watch.close()
    heights, fitness = offline(GENOME, ROBOTS, steps, 3)
    assert np.array_equal(result.heights, heights) and result.fitness == fitness


@pytest.mark.system
def test_robot_hidden_from_the_camera_stops_is_disabled_and_the_others_finish(domain):
    steps, hidden = 14, 2
    watch = OperatorWatcher(domain)
    try:
        thread, out = start_trial(
            domain, steps, perception="full", command_timeout=20.0, timeout=900.0
        )
        assert watch.spin_until(lambda: watch.tick >= 3, timeout=600)
        occlude(watch, "2:front,2:rear", timeout=30.0)
        hidden_at = watch.tick
        assert watch.spin_until(
            lambda: watch.enabled[hidden] and not watch.enabled[hidden][-1], 600
        )
        lost_at = watch.tick
        result = finish(watch, thread, out)
    finally:
        watch.close()
    commands = np.array(result.commands)
    print(
        f"robot {hidden} hidden at tick {hidden_at}, stopped and absent at tick {lost_at}; "
        f"fitness {result.fitness:.4f} after {steps} ticks, missed {result.missed}, "
        f"{result.seconds:.0f} s"
    )
    assert len(result.trace) == steps + 1
    assert (commands[lost_at + 1 :, hidden] == 0).all()  # it stays stopped
    others = [k for k in range(ROBOTS) if k != hidden]
    assert commands[lost_at + 1 :, others].any()  # the other three carry on
    # Only the ticks before the supervisor stopped it were lost to the team.
    assert max(result.missed[k] for k in others) <= lost_at - hidden_at + 1


@pytest.mark.system
def test_a_trial_a_script_started_in_the_background_stops_on_sigint(domain):
    """A shell without job control starts ``cmd &`` with SIGINT ignored, and Python keeps an
    inherited ignore: ``ant-trial`` (nodes composed on a context of its own, so no rclpy
    handler) ran on at full CPU after the Ctrl-C of docs/operator.md's session. It now
    stops on SIGINT however it was started, closing its nodes, with exit code 130."""
    watch = OperatorWatcher(domain)
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    trial = subprocess.Popen(
        [str(Path(sys.executable).parent / "ant-trial"), "--genome", str(GENOME),
         "--robots", "2", "--steps", "100000", "--domain", str(domain)],
        cwd=Path(__file__).parents[1], env=env, stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE, text=True, start_new_session=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN),
    )  # fmt: skip
    try:
        assert watch.spin_until(lambda: watch.tick >= 3, timeout=120), "the trial never ticked"
        trial.send_signal(signal.SIGINT)
        _, err = trial.communicate(timeout=60)
    finally:
        if trial.poll() is None:
            trial.kill()
            trial.wait()
        watch.close()
    assert trial.returncode == 130, err
    assert "interrupted" in err
