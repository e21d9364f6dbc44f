"""The dome's process supervisor as a pure state machine: order, restarts, shutdown."""

from __future__ import annotations

from excavation_bringup.nodes import NodeSpec
from excavation_bringup.supervise import Kill, Report, RestartPolicy, Start, Stop, Supervisor

POLICY = RestartPolicy(
    backoff=1.0,
    factor=2.0,
    max_backoff=5.0,
    max_restarts=3,
    stable_after=60.0,
    ready_timeout=20.0,
    stop_timeout=4.0,
)


def make(final_last=False, restart=True):
    specs = [
        NodeSpec("a", "m", {}, ("a",)),
        NodeSpec("b", "m", {}, ("b",), restart=restart),
        NodeSpec("c", "m", {}, ("c",), final=final_last),
    ]
    return Supervisor.create(specs, POLICY)


KINDS = {"start": Start, "stop": Stop, "kill": Kill}


def kinds(actions, kind):
    return [a.name for a in actions if type(a) is KINDS[kind]]


def start_all(sup, now=0.0):
    for name in ("a", "b", "c"):
        assert kinds(sup.poll(now), "start") == [name]
        assert kinds(sup.poll(now), "start") == []  # waits for name's diagnostics
        sup.ready(name, now)
    actions = sup.poll(now)
    assert any("all 3 nodes are up" in a.text for a in actions if isinstance(a, Report))
    assert sup.phase == "running"


def test_nodes_start_in_order_each_after_the_one_before_reports():
    sup = make()
    start_all(sup)


def test_a_crashed_node_restarts_with_growing_back_off():
    sup = make()
    start_all(sup)
    delays = []
    now = 10.0
    for _ in range(3):
        sup.exited("b", -9, now)
        reports = [a.text for a in sup.poll(now) if isinstance(a, Report)]
        assert "b exited with code -9" in reports
        restart_at = sup.child("b").next_start
        delays.append(restart_at - now)
        assert kinds(sup.poll(restart_at - 0.01), "start") == []
        assert kinds(sup.poll(restart_at), "start") == ["b"]
        sup.ready("b", restart_at + 1)
        assert any(
            "b is up again" in a.text for a in sup.poll(restart_at + 1) if isinstance(a, Report)
        )
        now = restart_at + 2
    assert delays == [1.0, 2.0, 4.0]
    sup.exited("b", 1, now)  # the fourth crash within a minute: give up
    actions = sup.poll(now)
    assert "crashed 4 times" in sup.failure
    assert kinds(actions, "stop") == ["c"]  # reverse order


def test_a_node_up_for_long_has_its_restarts_forgiven():
    sup = make()
    start_all(sup)
    sup.exited("b", 1, 1.0)
    sup.poll(2.0)
    sup.ready("b", 2.5)
    sup.exited("b", 1, 100.0)  # up for a long time since
    sup.poll(100.0)
    assert sup.child("b").next_start == 101.0  # the first delay again


def test_exit_code_2_and_unrestartable_nodes_end_the_run():
    sup = make()
    start_all(sup)
    sup.exited("a", 2, 5.0)
    assert "a refused its configuration" in sup.failure
    sup = make(restart=False)
    start_all(sup)
    sup.exited("b", -11, 5.0)
    assert "b crashed and is not restartable" in sup.failure


def test_the_final_node_finishing_stops_the_rest_in_reverse_order_with_kill():
    sup = make(final_last=True)
    start_all(sup)
    sup.exited("c", 0, 50.0)
    assert sup.finished and not sup.failure
    actions = sup.poll(50.0)
    assert kinds(actions, "stop") == ["b"]
    assert kinds(sup.poll(51.0), "stop") == []  # one at a time
    sup.exited("b", 0, 52.0)
    assert kinds(sup.poll(52.0), "stop") == ["a"]
    assert kinds(sup.poll(56.5), "kill") == ["a"]  # outlived stop_timeout
    sup.exited("a", -9, 57.0)
    sup.poll(57.0)
    assert sup.done


def test_shutdown_during_start_up_and_a_node_that_never_reports():
    sup = make()
    assert kinds(sup.poll(0.0), "start") == ["a"]
    sup.ready("a", 0.5)
    assert kinds(sup.poll(1.0), "start") == ["b"]
    actions = sup.poll(30.0)  # b never reported
    assert "b did not report on /diagnostics within 20 s" in sup.failure
    assert kinds(actions, "stop") == ["b"]
    sup.exited("b", -2, 31.0)
    assert kinds(sup.poll(31.0), "stop") == ["a"]
    assert sup.child("c").state == "stopped"  # never started
    sup.exited("a", 0, 32.0)
    sup.poll(32.0)
    assert sup.done


def test_ctrl_c_stops_everything_and_a_crash_in_back_off_is_not_restarted():
    sup = make()
    start_all(sup)
    sup.exited("a", 1, 3.0)
    sup.stop(3.5, "SIGINT")
    assert not sup.failure
    assert kinds(sup.poll(10.0), "start") == []
    assert sup.child("a").state == "stopped"


def test_every_action_is_one_frozen_dataclass_per_kind():
    import dataclasses

    import pytest

    sup = make(final_last=True)
    seen = []
    for name in ("a", "b", "c"):
        seen += sup.poll(0.0)
        sup.ready(name, 0.0)
    seen += sup.poll(0.0)
    sup.exited("b", 1, 1.0)
    seen += sup.poll(5.0)
    sup.exited("c", 0, 6.0)
    for t in (6.0, 30.0):
        seen += sup.poll(t)
    assert {type(a) for a in seen} == {Start, Stop, Kill, Report}
    for action in seen:
        assert dataclasses.is_dataclass(action)
        with pytest.raises(dataclasses.FrozenInstanceError):
            action.name = "x"


def test_the_operators_actions_reach_the_events_log_once_each_with_their_origin():
    from diagnostic_msgs.msg import DiagnosticStatus, KeyValue

    from excavation_bringup.supervise import Report, control_reports

    def status(name, action):
        values = [KeyValue(key="controls", value="1")]
        if action is not None:
            values.append(KeyValue(key="last_control", value=action))
        return DiagnosticStatus(name=name, values=values)

    last: dict[str, str] = {}
    view = status("/ant_view", "estop from view client 2: done: e-stop latched")
    assert control_reports([view, status("/robot_0/executor", None)], last) == [
        Report("operator: estop from view client 2: done: e-stop latched (/ant_view)")
    ]
    assert control_reports([view], last) == []  # the same action again: once only
    console = status("/ant_operator_7", "arm from the console")
    assert control_reports([console], last) == [
        Report("operator: arm from the console (/ant_operator_7)")
    ]
