"""Ctrl-C stops a command as an interruption wherever it lands, rclpy's bindings included."""

import os
import signal

import pytest

from excavation_bringup import trial
from excavation_common import signals

RCLPY_CAST_ERROR = "Unable to convert call argument '0' to Python object"


@pytest.fixture
def sigint():
    """Install the commands' SIGINT handler for one test, with no signal received yet."""
    before = signal.getsignal(signal.SIGINT)
    signals._received = 0
    signals.interrupt_on_sigint()
    yield
    signal.signal(signal.SIGINT, before)
    signals._received = 0


def _kill_inside_rclpy():
    """What rclpy's bindings do with a Ctrl-C that arrives while they build a message."""
    try:
        os.kill(os.getpid(), signal.SIGINT)
        signal.sigtimedwait([], 0)  # let the handler run here
    except KeyboardInterrupt:
        raise RuntimeError(RCLPY_CAST_ERROR) from None


def test_sigint_raises_keyboard_interrupt_and_is_remembered(sigint):
    assert not signals.interrupted()
    with pytest.raises(KeyboardInterrupt):
        os.kill(os.getpid(), signal.SIGINT)
        signal.sigtimedwait([], 0)
    assert signals.interrupted()


def test_keep_interrupts_turns_a_runtime_error_after_sigint_back_into_an_interrupt(sigint):
    with pytest.raises(RuntimeError, match="not a signal"), signals.keep_interrupts():
        raise RuntimeError("not a signal")
    with pytest.raises(KeyboardInterrupt), signals.keep_interrupts():
        _kill_inside_rclpy()


def test_ant_trial_stopped_inside_rclpy_exits_130_not_2(monkeypatch, capsys):
    before = signal.getsignal(signal.SIGINT)
    signals._received = 0
    monkeypatch.setattr(trial, "run_trial", lambda *a, **k: _kill_inside_rclpy())
    try:
        assert trial.main(["--genome", "genomes/best.json", "--steps", "5"]) == 130
    finally:
        signal.signal(signal.SIGINT, before)
        signals._received = 0
    err = capsys.readouterr().err
    assert "interrupted" in err and RCLPY_CAST_ERROR not in err


def test_ant_trial_reports_a_runtime_error_without_sigint_as_an_error(monkeypatch, capsys):
    before = signal.getsignal(signal.SIGINT)
    signals._received = 0

    def fail(*a, **k):
        raise RuntimeError("a node process failed")

    monkeypatch.setattr(trial, "run_trial", fail)
    try:
        assert trial.main(["--genome", "genomes/best.json", "--steps", "5"]) == 2
    finally:
        signal.signal(signal.SIGINT, before)
    assert "ant-trial: error: a node process failed" in capsys.readouterr().err
