"""The blade driver under the team's oversight: e-stop, pause, disable, deadman, lifecycle;
and a serial port that is absent at start, unplugged and plugged in again."""

from __future__ import annotations

import os
import threading
import time

import pytest
from builtin_interfaces.msg import Time
from helpers.blades import blade_driver_node, blade_probe, blade_supervisor, word
from std_msgs.msg import Float64MultiArray, UInt16

from ant_controller.layout import BLADE_BELOW_CMD
from blade_driver.fake_board import FakeBoard, open_pty
from blade_driver.hardware import joint_state
from blade_driver.protocol import ServoCalibration

HOME = 0.10


@pytest.fixture
def sim(ros):
    """Supervisor (armed), sim-backend driver and a probe; tick 0 answered with 'below'."""
    sup = blade_supervisor(ros)
    drv = blade_driver_node(ros, supervised=False, backend="sim")
    probe = blade_probe(ros)
    assert ros.spin_until(lambda: probe.count_subscribers("/robot_0/blade/servo_state") > 0)
    assert ros.spin_until(lambda: drv.hold is None)
    probe.state.publish(joint_state(HOME, 0.0, Time(sec=0)))
    assert ros.spin_until(lambda: probe.joints)
    probe.behaviour.publish(UInt16(data=word(BLADE_BELOW_CMD)))
    assert ros.spin_until(lambda: probe.servo)
    assert probe.servo[-1].position == pytest.approx(-0.02)
    assert not probe.servo[-1].held
    return sup, drv, probe


def change(ros, sup, action, *args):
    """Apply a supervisor action as its service would; the wall time it went out."""
    getattr(sup.team, action)(*args)
    sent = time.monotonic()
    sup.announce()
    return sent


def held(probe, n):
    return len(probe.servo) > n and probe.servo[-1].held


@pytest.mark.parametrize(
    ("stop", "go"),
    [
        ([("estop",)], [("reset",), ("arm",)]),
        ([("pause",)], [("resume",)]),
        ([("enable", 0, False)], [("enable", 0, True)]),
    ],
    ids=["estop", "pause", "disable"],
)
def test_sim_blade_goes_home_and_returns_to_the_ticks_setpoint(ros, sim, stop, go):
    sup, drv, probe = sim
    n = len(probe.servo)
    sent = change(ros, sup, *stop[0])
    assert ros.spin_until(lambda: held(probe, n), timeout=5)
    print(f"{stop[0][0]}: blade home {1e3 * (time.monotonic() - sent):.1f} ms after the change")
    cmd = probe.servo[-1]
    assert cmd.position == pytest.approx(HOME) and cmd.stamp.sec == 0
    assert drv.core.state.setpoint == pytest.approx(-0.02)  # the core is left as it was
    for action in go[:-1]:  # e-stop: reset alone leaves the team disarmed, the blade home
        change(ros, sup, *action)
        ros.spin_until(lambda: False, timeout=0.5)
        assert probe.servo[-1].held
    n = len(probe.servo)
    change(ros, sup, *go[-1])
    assert ros.spin_until(lambda: len(probe.servo) > n, timeout=5)
    again = probe.servo[-1]
    assert not again.held and again.stamp.sec == 0
    assert again.position == pytest.approx(-0.02)  # the tick's own set-point, unchanged


def test_sim_blade_homes_on_heartbeat_loss_and_lifecycle(ros, sim):
    sup, drv, probe = sim
    n = len(probe.servo)
    drv.trigger_deactivate()
    assert ros.spin_until(lambda: held(probe, n)) and "not active" in drv.hold
    drv.trigger_activate()
    assert ros.spin_until(lambda: not probe.servo[-1].held)
    n = len(probe.servo)
    ros.executor.remove_node(sup)  # the supervisor dies
    killed = time.monotonic()
    sup.destroy_node()
    assert ros.spin_until(lambda: held(probe, n), timeout=5)
    print(f"heartbeat loss: blade home {time.monotonic() - killed:.3f} s after the supervisor died")
    assert "heartbeat lost" in drv.hold


def test_an_unarmed_team_never_moves_the_blade(ros):
    blade_supervisor(ros, armed=False)
    drv = blade_driver_node(ros, supervised=False, backend="sim")
    probe = blade_probe(ros)
    assert ros.spin_until(lambda: probe.count_subscribers("/robot_0/blade/servo_state") > 0)
    assert ros.spin_until(lambda: drv.hold == "team disarmed")
    for t in range(3):
        probe.state.publish(joint_state(HOME, 0.0, Time(sec=t)))
        probe.behaviour.publish(UInt16(data=word(BLADE_BELOW_CMD)))
        probe.override.publish(Float64MultiArray(data=[-0.03]))
        ros.spin_until(lambda t=t: probe.servo and probe.servo[-1].stamp.sec == t, 3)
    assert probe.servo and all(m.position == pytest.approx(HOME) and m.held for m in probe.servo)


class Plug:
    """A fake servo board behind a fixed path (a symlink, as udev's /dev/serial/by-id)."""

    def __init__(self, link):
        self.link, self.board, self.master, self.thread = link, None, None, None
        self.stop = threading.Event()

    def plug(self):
        self.board = FakeBoard()
        self.master, path = open_pty()
        self.stop = threading.Event()
        self.thread = threading.Thread(
            target=self.board.serve, args=(self.master, self.stop.is_set), daemon=True
        )
        self.thread.start()
        os.symlink(path, self.link)

    def unplug(self):
        os.unlink(self.link)
        self.stop.set()
        self.thread.join(timeout=2)
        os.close(self.master)


def test_serial_port_absent_at_start_then_unplugged_and_replugged(ros, tmp_path):
    link = str(tmp_path / "ttyBLADE")
    plug = Plug(link)
    blade_supervisor(ros)
    drv = blade_driver_node(
        ros,
        supervised=False,
        backend="serial",
        port=link,
        rate=50.0,
        reopen_initial=0.05,
        reopen_max=0.2,
    )
    probe = blade_probe(ros)
    cal = ServoCalibration()

    def diag(text):
        return any(text in s.message for s in probe.diags)

    assert ros.spin_until(lambda: diag("cannot open") and drv.hw.backoff.failures >= 3)
    assert probe.diags[-1].level == b"\x02"
    plug.plug()
    assert ros.spin_until(lambda: plug.board.set_points, timeout=10)  # found without a restart
    assert drv.hw.reopened == 1
    below = UInt16(data=word(BLADE_BELOW_CMD))

    def commanded(angle):
        def check():
            probe.behaviour.publish(below)
            return plug.board.target == pytest.approx(angle)

        return check

    assert ros.spin_until(commanded(cal.angle(-0.02)))
    plug.unplug()
    assert ros.spin_until(lambda: diag("port closed, reopening"), timeout=10)
    assert drv.hw.board is None
    plug.plug()
    assert ros.spin_until(commanded(cal.angle(-0.02)), timeout=10)
    assert drv.hw.reopened == 2 and drv.hw.backoff.failures == 0

    def reopened_twice():
        values = {v.key: v.value for v in probe.diags[-1].values}
        return values["port_open"] == "True" and values["reopened"] == "2"

    assert ros.spin_until(reopened_twice)
    # The e-stop sends the real blade home too.
    sup = next(n for n in ros.executor.get_nodes() if n.get_name() == "supervisor")
    sent = change(ros, sup, "estop")
    assert ros.spin_until(lambda: plug.board.target == pytest.approx(cal.angle(HOME)))
    print(f"serial e-stop: board told home {1e3 * (time.monotonic() - sent):.1f} ms after")
    plug.unplug()
