"""``ant-soak``: a long trial through the nodes, watching every process's memory.

Runs a lockstep trial with every node its own process (what ``ant-trial --processes``
runs: :class:`excavation_bringup.launch.ProcessLauncher`), by default 4 robots for 10,000
ticks with full perception (sensors, localizer, mapper), and samples the resident memory
(``VmRSS`` of ``/proc/PID/status``) of every node every ``--interval`` seconds together with
the tick (``/clock``). At the end it reports, per process, the growth from the end of the
warm-up to the end and the slope of a straight line fitted to the samples after the warm-up
(MB per 1000 ticks), and fails (exit code 1) when a process grows beyond the bounds or a
robot missed a tick::

    ant-soak --steps 10000 --json soak.json --plot docs/figures/soak_memory.png
    ant-soak --steps 300 --robots 2 --max-growth 20   # a quick one

``make soak`` runs the default soak. Traffic stays on loopback
(``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` unless set); ``--domain`` picks the ROS domain.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from excavation_bringup.deployment import Deployment
from excavation_bringup.graph import build
from excavation_bringup.launch import ProcessLauncher


def rss_mb(pid: int) -> float | None:
    """Resident memory of process ``pid`` in MB (``VmRSS``), or None when it is gone."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    except (FileNotFoundError, ProcessLookupError, PermissionError, ValueError):
        return None
    return None


@dataclass(frozen=True)
class Growth:
    """How one process's memory changed after the warm-up.

    Attributes:
        name: The node.
        start_mb: RSS at the first sample after the warm-up.
        end_mb: RSS at the last sample.
        peak_mb: Highest RSS after the warm-up.
        slope_mb_per_1000: Least-squares slope of RSS over ticks after the warm-up.
    """

    name: str
    start_mb: float
    end_mb: float
    peak_mb: float
    slope_mb_per_1000: float

    @property
    def growth_mb(self) -> float:
        """End minus start."""
        return self.end_mb - self.start_mb


def memory_growth(samples: list[dict], warmup: int) -> list[Growth]:
    """Per process, the growth after tick ``warmup`` (samples: ``{"tick", "rss": {name: MB}}``).

    Raises:
        ValueError: Fewer than two samples after the warm-up.
    """
    after = [s for s in samples if s["tick"] >= warmup]
    if len(after) < 2:
        raise ValueError(f"{len(after)} samples after the warm-up (tick {warmup}): need 2")
    names = sorted({n for s in after for n in s["rss"]})
    out = []
    for name in names:
        points = [(s["tick"], s["rss"][name]) for s in after if name in s["rss"]]
        ticks = np.array([p[0] for p in points], dtype=float)
        mb = np.array([p[1] for p in points], dtype=float)
        slope = float(np.polyfit(ticks, mb, 1)[0]) * 1000 if np.ptp(ticks) > 0 else 0.0
        out.append(Growth(name, float(mb[0]), float(mb[-1]), float(mb.max()), slope))
    return out


def violations(growth: list[Growth], max_growth: float, max_slope: float) -> list[str]:
    """One line per process beyond a bound (MB after the warm-up, MB per 1000 ticks)."""
    out = []
    for g in growth:
        if g.growth_mb > max_growth:
            out.append(f"{g.name}: grew {g.growth_mb:.1f} MB after warm-up (bound {max_growth})")
        if g.slope_mb_per_1000 > max_slope:
            out.append(f"{g.name}: {g.slope_mb_per_1000:.2f} MB per 1000 ticks (bound {max_slope})")
    return out


class _ClockWatcher:
    """The latest tick (``/clock`` seconds), from a node spun in a background thread."""

    def __init__(self, domain: int) -> None:
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node
        from rclpy.signals import SignalHandlerOptions
        from rosgraph_msgs.msg import Clock

        self.tick = -1
        self.context = Context()
        # Ctrl-C must reach the soak's loop (which stops the nodes), not only rclpy.
        from excavation_common.ros import init_rclpy

        init_rclpy(
            context=self.context,
            domain_id=domain,
            signal_handler_options=SignalHandlerOptions.NO,
        )
        self.node = Node("soak_clock", context=self.context)
        self.node.create_subscription(Clock, "/clock", self._on_clock, 10)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _on_clock(self, msg) -> None:
        self.tick = int(msg.clock.sec)

    def _spin(self) -> None:
        from rclpy.executors import ExternalShutdownException

        try:
            while self.context.ok():
                self.executor.spin_once(timeout_sec=0.1)
        except (ExternalShutdownException, RuntimeError):
            pass

    def close(self) -> None:
        import rclpy

        rclpy.try_shutdown(context=self.context)
        self.thread.join(timeout=5.0)
        self.node.destroy_node()


def run_soak(spec: Deployment, interval: float, workdir: str | Path, progress=None) -> dict:
    """Run the trial of ``spec`` as processes, sampling memory; the samples and the result.

    Ctrl-C (or SIGTERM) stops the soak early: the nodes are stopped and the samples so far
    returned, with ``"result": None``.

    Returns:
        ``{"samples": [{"tick", "seconds", "rss": {node: MB}}], "result": sim result,
        "seconds": wall time}``.
    """
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

    def stop(_signum, _frame):
        raise KeyboardInterrupt  # SIGTERM (and SIGINT, even where a shell ignored it)

    previous = {sig: signal.signal(sig, stop) for sig in (signal.SIGTERM, signal.SIGINT)}
    watcher = _ClockWatcher(spec.domain)
    samples = []
    result = None
    started = time.monotonic()
    try:
        with ProcessLauncher(build(spec, workdir)) as trial:
            trial.start()
            next_sample = time.monotonic()
            while not trial.finished:
                if time.monotonic() - started > spec.timeout:
                    raise TimeoutError(f"soak did not finish within {spec.timeout} s")
                trial.check()
                if time.monotonic() >= next_sample and watcher.tick >= 0:
                    rss = {n: rss_mb(p.pid) for n, p in trial.procs.items()}
                    sample = {
                        "tick": watcher.tick,
                        "seconds": round(time.monotonic() - started, 2),
                        "rss": {n: round(v, 2) for n, v in rss.items() if v is not None},
                    }
                    samples.append(sample)
                    if progress is not None:
                        progress(sample)
                    next_sample = max(next_sample + interval, time.monotonic())
                time.sleep(0.1)
            result = trial.wait(spec.timeout, started)
    except KeyboardInterrupt:
        print("ant-soak: interrupted; the samples so far follow", file=sys.stderr)
    finally:
        watcher.close()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    return {"samples": samples, "result": result, "seconds": time.monotonic() - started}


def plot_memory(samples: list[dict], path: str | Path, title: str, warmup: int) -> None:
    """RSS of every process over ticks (one line per process), and the tick rate below it."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = sorted({n for s in samples for n in s["rss"]})
    fig, (ax, rate) = plt.subplots(
        2, 1, figsize=(8, 6), sharex=True, gridspec_kw={"height_ratios": [3, 1]}
    )
    for name in names:
        pts = [(s["tick"], s["rss"][name]) for s in samples if name in s["rss"]]
        ax.plot([p[0] for p in pts], [p[1] for p in pts], label=name, linewidth=1)
    ax.axvline(warmup, color="grey", linestyle=":", label="end of warm-up")
    ax.set_ylabel("resident memory (MB)")
    ax.set_title(title)
    ax.legend(fontsize=7, ncol=2, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    # ticks per wall second between consecutive samples: a slowdown shows as a drop
    pairs = list(zip(samples, samples[1:], strict=False))
    rate.plot(
        [b["tick"] for _, b in pairs],
        [(b["tick"] - a["tick"]) / max(b["seconds"] - a["seconds"], 1e-9) for a, b in pairs],
        color="black",
        linewidth=1,
    )
    rate.set_ylim(bottom=0)
    rate.set_xlabel("tick")
    rate.set_ylabel("ticks / s")
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``ant-soak``."""
    p = argparse.ArgumentParser(prog="ant-soak", description=__doc__.split("\n\n")[0])
    who = p.add_mutually_exclusive_group()
    who.add_argument("--genome", metavar="FILE", default="genomes/best.json")
    who.add_argument("--hand-coded", action="store_true")
    p.add_argument("--robots", type=int, default=4)
    p.add_argument("--steps", type=int, default=10_000)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--blueprint", default="default:1")
    p.add_argument("--perception", choices=("truth", "full"), default="full")
    p.add_argument("--command-timeout", type=float, default=30.0, metavar="S")
    p.add_argument("--interval", type=float, default=10.0, metavar="S", help="between samples")
    p.add_argument("--warmup", type=int, default=None, help="ticks (default: 10%% of steps)")
    p.add_argument("--max-growth", type=float, default=10.0, metavar="MB")
    p.add_argument("--max-slope", type=float, default=1.0, metavar="MB", help="per 1000 ticks")
    p.add_argument("--timeout", type=float, default=7 * 24 * 3600.0, metavar="S")
    p.add_argument("--domain", type=int, default=None)
    p.add_argument("--json", metavar="FILE", help="write samples, result and figures here")
    p.add_argument("--plot", metavar="PNG", help="memory over ticks")
    p.add_argument("--workdir", metavar="DIR", help="keep the node logs here")
    args = p.parse_args(argv)
    for name, value, low in (
        ("--robots", args.robots, 1),
        ("--steps", args.steps, 10),
        ("--interval", args.interval, 0.1),
    ):
        if value < low:
            print(f"ant-soak: error: {name} = {value}: must be at least {low}", file=sys.stderr)
            return 2
    warmup = args.warmup if args.warmup is not None else max(args.steps // 10, 5)
    domain = args.domain if args.domain is not None else int(os.environ.get("ROS_DOMAIN_ID", "0"))
    spec = Deployment(
        "hand-coded" if args.hand_coded else args.genome,
        args.robots,
        args.steps,
        args.seed,
        args.blueprint,
        0,
        domain,
        args.command_timeout,
        args.timeout,
        True,
        None,
        args.perception,
        processes=True,
    )

    def progress(sample: dict) -> None:
        total = sum(sample["rss"].values())
        print(
            f"ant-soak: tick {sample['tick']:>6} at {sample['seconds']:>8.1f} s: "
            f"{len(sample['rss'])} processes, {total:.0f} MB",
            file=sys.stderr,
            flush=True,
        )

    from excavation_common.errors import FieldError

    try:
        with tempfile.TemporaryDirectory(prefix="ant-soak-") as tmp:
            soak = run_soak(spec, args.interval, args.workdir or tmp, progress)
            growth = memory_growth(soak["samples"], warmup)
    except (FieldError, TimeoutError, RuntimeError, ValueError) as exc:
        print(f"ant-soak: error: {exc}", file=sys.stderr)
        return 2
    ticks = soak["samples"][-1]["tick"] if soak["result"] is None else args.steps
    result = soak["result"] or {"missed": None, "fitness": None}
    missed = sum(result["missed"].values()) if result["missed"] is not None else 0
    problems = violations(growth, args.max_growth, args.max_slope)
    if missed:
        problems.append(f"{missed} missed ticks: {result['missed']}")
    if soak["result"] is None:
        problems.append(f"interrupted at tick {ticks} of {args.steps}")
    print(
        f"ant-soak: {ticks} ticks, {args.robots} robots, perception {args.perception}: "
        f"{soak['seconds']:.0f} s ({ticks / soak['seconds']:.2f} ticks/s), "
        f"missed ticks {result['missed']}, fitness {result['fitness']}"
    )
    print(f"{'process':<16} {'start MB':>9} {'end MB':>8} {'peak MB':>8} {'MB/1000 ticks':>14}")
    for g in growth:
        print(
            f"{g.name:<16} {g.start_mb:>9.1f} {g.end_mb:>8.1f} {g.peak_mb:>8.1f} "
            f"{g.slope_mb_per_1000:>14.3f}"
        )
    if args.json:
        summary = {
            "steps": args.steps,
            "ticks": ticks,
            "robots": args.robots,
            "perception": args.perception,
            "seconds": soak["seconds"],
            "warmup": warmup,
            "missed": result["missed"],
            "fitness": result["fitness"],
            "growth": [{**g.__dict__, "growth_mb": g.growth_mb} for g in growth],
            "samples": soak["samples"],
            "problems": problems,
        }
        Path(args.json).write_text(json.dumps(summary, indent=1))
    if args.plot:
        title = f"ant-soak: {args.robots} robots, {ticks} ticks, perception {args.perception}"
        plot_memory(soak["samples"], args.plot, title, warmup)
    for line in problems:
        print(f"ant-soak: FAIL: {line}", file=sys.stderr)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
