"""The shared test helpers that no test module exercises otherwise, and the domain fixtures.

The watchers and the occlusion sequence (``tests/helpers/watchers.py``) run here against
stand-in nodes in the watcher's own context: a ``/sensors`` node with the ``occlude``
parameter and a Trigger service, ``/clock``, ``/diagnostics`` and blade set-point publishers.
"""

from __future__ import annotations

import time

from helpers.watchers import FaultWatcher, OperatorWatcher, occlude


def test_domain_fixtures_hand_out_fresh_ids_of_the_range(domain, domains):
    first = domains(2)
    taken = [domain, first, first + 1, domains()]
    assert all(1 <= d <= 100 for d in taken)
    assert len(set(taken)) == len(taken)


def test_operator_watcher_hears_the_trial_calls_services_and_occludes(domain):
    import rclpy
    from builtin_interfaces.msg import Time
    from excavation_interfaces.msg import BladeCommand
    from rosgraph_msgs.msg import Clock
    from std_srvs.srv import Trigger

    watch = OperatorWatcher(domain, robots=1)
    sensors = rclpy.create_node("sensors", context=watch.context)
    try:
        sensors.declare_parameter("occlude", "")
        calls = []

        def on_trigger(request, response):
            calls.append(request)
            response.success, response.message = True, "stand-in"
            return response

        sensors.create_service(Trigger, "/supervisor/arm", on_trigger)
        clock = sensors.create_publisher(Clock, "/clock", 10)
        servo = sensors.create_publisher(BladeCommand, "/robot_0/blade/servo_command", 10)
        watch.executor.add_node(sensors)
        assert watch.spin_until(
            lambda: clock.get_subscription_count() and servo.get_subscription_count(), 10
        )
        clock.publish(Clock(clock=Time(sec=3)))
        assert watch.spin_until(lambda: watch.tick == 3, 10)
        assert watch.tick_wall[-1][0] == 3
        reply, sent = watch.call("/supervisor/arm", timeout=10.0)
        assert reply.success and reply.message == "stand-in" and len(calls) == 1
        servo.publish(BladeCommand(stamp=Time(sec=3), position=0.10, held=True))
        assert watch.spin_until(lambda: 0 in watch.held_since(sent), 10)
        assert watch.servo[0][-1][1:] == (3, 0.10, True)
        occlude(watch, "2:front,2:rear", timeout=10.0)
        assert sensors.get_parameter("occlude").value == "2:front,2:rear"
    finally:
        watch.executor.remove_node(sensors)
        sensors.destroy_node()
        watch.close()


def test_fault_watcher_keeps_ticks_and_statuses_from_its_thread(domain):
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
    from excavation_interfaces.msg import Tick

    watch = FaultWatcher(domain, "truth", continuous=True)
    node = rclpy.create_node("stand_in", context=watch.context)  # publishes only: not spun
    try:
        tick = node.create_publisher(Tick, "/team/tick", 10)
        diag = node.create_publisher(DiagnosticArray, "/diagnostics", 10)
        status = DiagnosticStatus(
            level=DiagnosticStatus.WARN, name="/sim", message="m", values=[KeyValue(key="k")]
        )
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline:
            tick.publish(Tick(tick=7))
            diag.publish(DiagnosticArray(status=[status]))
            with watch.lock:
                if watch.tick == 7 and any(s.tick == 7 for s in watch.statuses):
                    break
            time.sleep(0.05)
        with watch.lock:
            assert watch.tick == 7 and 7 in watch.ticks_seen
            heard = [s for s in watch.statuses if s.tick == 7]
        assert heard and heard[0].name == "/sim" and heard[0].message == "m"
        assert heard[0].level == 1 and heard[0].values == {"k": ""}
    finally:
        node.destroy_node()
        watch.close()
    assert not watch.thread.is_alive()
