"""A peer SIGKILLed again and again never takes down, nor costs a word to, the processes it
talked to.

CI once lost an xdist worker to a segmentation fault in libc right after a test SIGKILLed the
team supervisor, and a fault-matrix trial lost a robot's word when the bag recorder was
killed (docs/reliability.md, "A killed peer crashed its neighbours"). Here a composed 4-robot
lockstep trial runs in this very process while a bag recorder, which subscribes to every
topic of the trial, is started and SIGKILLed ten times mid-trial. This process must survive
(a crash here ends the pytest worker), the trial must miss no word and end bit-identical to
the offline evaluator, and each recorder must have been recording when it was killed.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from helpers.diagnostics import DiagnosticsProbe
from helpers.trials import GENOME, ROBOTS, finish, offline, start_trial
from helpers.watchers import OperatorWatcher

pytestmark = pytest.mark.system  # starts a recorder process per kill

KILLS = 10
STEPS = 120


def test_recorders_killed_ten_times_cost_the_trial_nothing(tmp_path, domain):
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain))
    watch = OperatorWatcher(domain)
    diagnostics = DiagnosticsProbe(watch.node)

    def recording(since: float) -> bool:
        """Whether a recorder reported messages recorded in a status heard after ``since``."""
        return any(
            h.wall > since and int(h.values.get("messages", 0)) > 0
            for h in diagnostics.heard(lambda name: name == "/bag_recorder")
        )

    recorder = None
    kills = []
    try:
        thread, out = start_trial(domain, STEPS)
        assert watch.spin_until(lambda: watch.tick >= 2)
        for n in range(KILLS):
            # The team waits while the recorder process starts (seconds on a loaded machine;
            # the trial would otherwise end first), then runs while it records.
            assert watch.call("/supervisor/pause")[0].success
            started = time.monotonic()
            recorder = subprocess.Popen(
                [sys.executable, "-m", "excavation_bags.cli", "record", "--out",
                 str(tmp_path / f"bag{n}")],
                env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            )  # fmt: skip
            assert watch.spin_until(lambda started=started: recording(started), 120), (
                f"recorder {n} never recorded"
            )
            tick = watch.tick
            assert watch.call("/supervisor/resume")[0].success
            assert watch.spin_until(lambda tick=tick: watch.tick >= tick + 3)
            recorder.send_signal(signal.SIGKILL)
            assert recorder.wait(timeout=30) == -signal.SIGKILL
            kills.append(watch.tick)
            recorder = None
        result = finish(watch, thread, out)
    finally:
        if recorder is not None and recorder.poll() is None:
            recorder.kill()
            recorder.wait(timeout=30)
        watch.close()
    heights, fitness = offline(GENOME, ROBOTS, STEPS, 3)
    print(f"recorders SIGKILLed at ticks {kills}; missed {result.missed}")
    assert len(kills) == KILLS and kills[-1] < STEPS  # every kill mid-trial
    assert result.missed == dict.fromkeys(range(ROBOTS), 0)
    assert np.array_equal(result.heights, heights) and result.fitness == fitness
