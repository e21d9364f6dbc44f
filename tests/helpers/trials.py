"""What the trial tests run and compare with.

* :data:`GENOME`, :data:`ROBOTS`: the shipped genome and the team size of the oversight
  tests;
* :func:`offline` and :func:`offline_trace`: the same scenario in the offline evaluator
  (what a trial through the nodes must equal);
* :func:`start_trial` and :func:`finish`: a lockstep trial (composed nodes) in a thread,
  and its end, watched by a :class:`helpers.watchers.OperatorWatcher`;
* :func:`stays_still`: no tick is applied while the simulator is held.

The single copy: the trial, oversight, peer-kill, fault and field-experiment test modules
import these.
"""

from __future__ import annotations

import threading
import time

GENOME = "genomes/best.json"
"""The shipped genome (a path relative to the repository root)."""
ROBOTS = 4
"""Robots of an oversight trial."""


def _controller(spec: str):
    from ant_controller.controller import Controller

    return Controller.from_spec(spec)


def offline(spec: str, robots: int, steps: int, seed: int):
    """Final heights and fitness of the same scenario in the offline evaluator.

    Args:
        spec: ``"hand-coded"`` or a genome file.
        robots, steps, seed: The trial's (blueprint ``default:1``, scenario 0).

    Returns:
        ``(heights, fitness)``; asserts the batched score equals the stepped world's.
    """
    from ant_evolution.evaluate import ScenarioSet, advance
    from blueprint_server.blueprint import default_blueprint

    ctl = _controller(spec)
    batch = ScenarioSet.create(default_blueprint(1), robots, 1, steps, seed)
    world = batch.world(0)
    advance(world, ctl, steps)
    assert batch.score(ctl)[0] == world.fitness()
    return world.heights, world.fitness()


def offline_trace(spec: str, robots: int, steps: int, seed: int):
    """:func:`offline` stepped one tick at a time, with the fitness after every tick.

    Returns:
        ``(heights, fitness, trace)``: ``trace`` has the fitness at tick 0 .. ``steps``.
    """
    from ant_evolution.evaluate import ScenarioSet, advance
    from blueprint_server.blueprint import default_blueprint

    ctl = _controller(spec)
    world = ScenarioSet.create(default_blueprint(1), robots, 1, steps, seed).world(0)
    trace = [world.fitness()]
    for _ in range(steps):
        advance(world, ctl, 1)
        trace.append(world.fitness())
    return world.heights, world.fitness(), trace


def start_trial(domain: int, steps: int, **kwargs):
    """Run a lockstep trial of :data:`GENOME` with :data:`ROBOTS` robots in a thread.

    Args:
        domain: Its ROS domain.
        steps: Its ticks.
        kwargs: ``seed`` (3), ``command_timeout`` (30 s), ``timeout`` (400 s) and any other
            keyword of :func:`excavation_bringup.trial.run_trial`.

    Returns:
        ``(thread, out)``: ``out`` gets ``"result"`` (the trial's) or ``"error"``.
    """
    from excavation_bringup.trial import run_trial

    out = {}

    def run():
        try:
            out["result"] = run_trial(
                GENOME,
                ROBOTS,
                steps,
                kwargs.pop("seed", 3),
                "default:1",
                domain=domain,
                command_timeout=kwargs.pop("command_timeout", 30.0),
                timeout=kwargs.pop("timeout", 400.0),
                **kwargs,
            )
        except Exception as exc:  # reported by the test
            out["error"] = exc

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return thread, out


def finish(watch, thread, out):
    """Spin ``watch`` until the trial's thread ends (400 s at most); its result."""
    assert watch.spin_until(lambda: not thread.is_alive(), timeout=400.0)
    thread.join()
    assert "error" not in out, out.get("error")
    return out["result"]


def stays_still(watch, reports: int = 2) -> bool:
    """No tick is applied while the simulator is live and held.

    Not a fixed wait (which a slow machine passes trivially): the simulator must say
    ``tick T held`` in ``reports`` of its periodic statuses (one a second) sent after the
    call, so it ran its loop meanwhile; then the tick must still be T.
    """
    since, tick = time.monotonic(), watch.tick

    def held() -> list[str]:
        return [m for w, m in watch.sim_reports if w >= since and m.startswith(f"tick {tick} held")]

    assert watch.spin_until(lambda: len(held()) >= reports, timeout=60), watch.sim_reports[-5:]
    return watch.tick == tick
