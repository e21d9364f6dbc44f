"""``ant-bag``: record, replay, inspect, recover and report ROS 2 bags of the node suite.

Examples::

    ant-bag record --out bags/run1                      # every suite topic, until Ctrl-C
    ant-bag record --out bags/run1 --topics '/robot_*/pose' /worksite/height_map --duration 60
    ant-bag info bags/sample
    ant-bag play bags/sample --rate 2 --loop
    ant-bag play bags/sample --lockstep --topics /blueprint/* /worksite/* '/robot_*/pose'
    ant-bag play runs/dome1 --clock --rate 4                   # a dome run, on its clock
    ant-bag play runs/dome1 --genome genomes/best.json         # tick replay: same words?
    ant-bag report bags/sample --out report/
    ant-bag diff runs/dome1 runs/dome1-reperceived             # topic by topic
    ant-bag recover crashed_bag --out repaired_bag      # a bag whose recorder was killed

``ros2 run excavation_bags ant-bag ...`` is the same program. ROS traffic stays on this machine
unless ``ROS_AUTOMATIC_DISCOVERY_RANGE`` says otherwise; ``--domain`` picks the ROS domain.
A bad bag or argument ends with exit code 2 and a message naming the bag, field and value.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import threading
import time

from excavation_common.errors import FieldError


def _spin(node_factory, domain: int | None, until, ros_args: list[str]) -> object:
    """Init rclpy on ``domain``, spin the node until ``until(node)`` or shutdown.

    ``ros_args`` (``--ros-args ...``, e.g. ``--params-file``) reach every node.
    """
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor

    context = Context()
    if domain is None:
        domain = int(os.environ.get("ROS_DOMAIN_ID", "0"))
    from excavation_common.ros import init_rclpy

    init_rclpy(args=["ant-bag", *ros_args], context=context, domain_id=domain)
    # Ctrl-C and SIGTERM only set a flag that the loop below checks: a KeyboardInterrupt
    # raised at a random point (inside a write, or inside rclpy) could leave the bag or
    # the executor half-done, and the bag must be finished cleanly.
    stopping: list[int] = []
    previous = {}
    if threading.current_thread() is threading.main_thread():
        for sig in (signal.SIGINT, signal.SIGTERM):
            previous[sig] = signal.signal(sig, lambda signum, _frame: stopping.append(signum))
    executor = SingleThreadedExecutor(context=context)
    node = None
    extras: list = []
    try:
        node = node_factory(context)
        if isinstance(node, tuple):  # (the node the loop watches, nodes spun beside it)
            node, extras = node
        for n in (node, *extras):
            executor.add_node(n)
        while context.ok() and not stopping and not until(node):
            executor.spin_once(timeout_sec=0.05)
    except ExternalShutdownException:
        pass
    finally:
        if node is not None:
            close = getattr(node, "close", None)
            if close is not None:
                close()
        for n in extras:  # a recorder among them finishes its bag
            close = getattr(n, "close", None)
            if close is not None:
                close()
        for n in ([node] if node is not None else []) + list(extras):
            executor.remove_node(n)
            n.destroy_node()
        executor.shutdown()
        rclpy.try_shutdown(context=context)
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    return node


def cmd_record(args: argparse.Namespace) -> int:
    """``ant-bag record``."""
    from rclpy.parameter import Parameter

    from excavation_bags.recorder_node import RecorderNode

    overrides = [Parameter("out", value=args.out)]
    if args.flush_period is not None:
        overrides.append(Parameter("flush_period", value=float(args.flush_period)))
    if args.height_unit is not None:
        overrides.append(Parameter("height_unit", value=float(args.height_unit)))
    if args.image_codec is not None:
        overrides.append(Parameter("image_codec", value=args.image_codec))
    if args.topics:
        overrides.append(Parameter("topics", value=list(args.topics)))
    started = time.monotonic()

    def until(_node) -> bool:
        return args.duration is not None and time.monotonic() - started >= args.duration

    def make(ctx) -> RecorderNode:
        node = RecorderNode(context=ctx, parameter_overrides=overrides)
        print(f"ant-bag: recording into {args.out} (Ctrl-C stops)", file=sys.stderr, flush=True)
        return node

    node = _spin(
        make,
        args.domain,
        until,
        args.ros_args,
    )
    if node is not None:
        counts = node.recorded
        print(f"ant-bag: {sum(counts.values())} messages on {len(counts)} topics in {args.out}")
        for topic, reason in node.skipped.items():
            print(f"ant-bag: warning: {topic} not recorded: {reason}", file=sys.stderr)
    return 0


def cmd_play(args: argparse.Namespace) -> int:
    """``ant-bag play``."""
    from rclpy.parameter import Parameter

    from excavation_bags.player_node import PlayerNode
    from excavation_bags.reader import open_bag

    bag = open_bag(args.bag)
    for w in bag.warnings:
        print(f"ant-bag: warning: {w}", file=sys.stderr)
    if args.genome or args.hand_coded:
        return tick_replay(args, bag)
    if args.reperceive:
        return reperceive(args, bag)
    overrides = [Parameter("bag", value=str(args.bag))]
    for name, value in (("rate", args.rate), ("delay", args.delay)):
        if value is not None:
            overrides.append(Parameter(name, value=float(value)))
    for name, flag in (("loop", args.loop), ("lockstep", args.lockstep)):
        if flag:
            overrides.append(Parameter(name, value=True))
    if args.topics:
        overrides.append(Parameter("topics", value=list(args.topics)))
    if args.wait_for:
        overrides.append(Parameter("wait_for", value=list(args.wait_for)))
    if args.exclude:
        overrides.append(Parameter("exclude", value=list(args.exclude)))
    if args.clock is not None:
        overrides += [Parameter("clock", value=True), Parameter("clock_rate", value=args.clock)]
    if args.start_offset is not None:
        overrides.append(Parameter("start_offset", value=float(args.start_offset)))
    progress = Progress(args.quiet)
    node = _spin(
        lambda ctx: PlayerNode(bag, context=ctx, parameter_overrides=overrides),
        args.domain,
        progress.update,
        args.ros_args,
    )
    progress.close()
    if node is not None:
        print(f"ant-bag: published {node.published} messages from {args.bag}")
    return 0


def reperceive(args: argparse.Namespace, bag) -> int:
    """``ant-bag play BAG --reperceive --out NEW``: the run's sensors, perceived again.

    A fresh localiser and mapper take the recorded sensor data; their poses and height maps
    go into ``NEW``.
    """
    from excavation_bags.reperceive import parameter_files, reperceive_nodes

    if not args.out:
        print("ant-bag: error: --reperceive needs --out NEW (the bag it records)", file=sys.stderr)
        return 2
    localizer, mapper = parameter_files(args.run_dir, args.localizer_params, args.mapper_params)
    progress = Progress(args.quiet)

    def make(ctx):
        return reperceive_nodes(bag, args.out, ctx, localizer, mapper, args.rate or 1.0)

    node = _spin(make, args.domain, progress.update, args.ros_args)
    progress.close()
    if node is None:
        return 1
    print(
        f"ant-bag: re-perceived {args.bag} into {args.out} (compare: ant-bag diff {args.bag} "
        f"{args.out} --topics '/robot_*/pose' /worksite/height_map)"
    )
    return 0


def tick_replay(args: argparse.Namespace, bag) -> int:
    """``ant-bag play BAG --genome G`` (or ``--hand-coded``): the tick replay.

    Fresh controllers decide every recorded tick again; exit 0 when every word came again,
    1 when some differ or are missing (as ``diff``).
    """
    import json

    from ant_controller.controller import Controller
    from excavation_bags.tick_replay import compare, recorded_robots, recorded_words, replay_nodes

    controller = Controller.hand_coded() if args.hand_coded else Controller.from_file(args.genome)
    parts: dict = {}

    def make(ctx):
        player, controllers, log, probe = replay_nodes(
            bag, controller, ctx, height_unit=args.height_unit, timeout=args.tick_timeout
        )
        parts.update(player=player, log=log)
        return player, [*controllers, probe]

    settle: list[float] = []

    def done(player) -> bool:  # finished, and a moment for the last words to arrive
        if not player.finished:
            return False
        settle.append(time.monotonic())
        return time.monotonic() - settle[0] > 1.0

    _spin(make, args.domain, done, args.ros_args)
    if "player" not in parts:
        return 1
    robots = recorded_robots(bag)
    log = parts["log"]
    result = compare(recorded_words(bag, robots), log.words, log.sensors)
    result["unanswered_ticks"] = parts["player"].missed
    if args.json:
        print(json.dumps(result))
    else:
        print(
            f"ant-bag: tick replay of {args.bag}: {result['ticks']} ticks x {len(robots)} robots "
            f"with {args.genome or 'the hand-coded rules'}"
        )
        if result["missing"] or result["unanswered_ticks"]:
            print(f"ant-bag: words missing: {result['missing']}; ticks not answered in "
                  f"{args.tick_timeout:g} s: {result['unanswered_ticks']}")  # fmt: skip
        if not result["differing"]:
            print("ant-bag: every recorded word came again")
        for d in result["differing"][: args.show]:
            print(
                f"ant-bag: tick {d['tick']} robot {d['robot']}: recorded {d['recorded']}, "
                f"replayed {d['replayed']} (sensor codes {d['sensors']})"
            )
        if len(result["differing"]) > args.show:
            print(f"ant-bag: ... {len(result['differing']) - args.show} more differing words")
    same = not result["differing"] and not result["missing"]
    return 0 if same else 1


class Progress:
    """The progress line of ``ant-bag play``: messages published and the bag time.

    ``update`` is the spin loop's stop test: true once the player finished.
    """

    def __init__(self, quiet: bool) -> None:
        self.quiet = quiet
        self.bar = None
        self.first = 0

    def update(self, node) -> bool:
        """Advance the line to ``node``'s position; the player finished."""
        if not self.quiet:
            if self.bar is None:
                from excavation_common.progress import tqdm

                total = len(node.messages) if not node.loop else None
                self.bar = tqdm(
                    total=total, unit="msg", desc="ant-bag play", mininterval=0.5, leave=True
                )
                self.first = node.bag.start_ns
            self.bar.update(node.published - self.bar.n)
            t = node.bag_time
            if t is not None:
                self.bar.set_postfix_str(
                    f"bag time {(t - self.first) * 1e-9:.1f} of {node.bag.duration_s:.1f} s",
                    refresh=False,
                )
        return node.finished

    def close(self) -> None:
        """End the line."""
        if self.bar is not None:
            self.bar.close()


def size_per_minute(bag) -> str:
    """``"12.3 MB/min"`` of a bag (file size over its recorded time span), or ``"-"``."""
    rate = bag.bytes_per_minute
    return "-" if rate is None else f"{rate / 1e6:.2f} MB/min"


def cmd_diff(args: argparse.Namespace) -> int:
    """``ant-bag diff A B``: 0 when the bags are the same, 1 when they differ (as ``diff``)."""
    import json

    from excavation_bags.diff import diff_bags, diff_lines
    from excavation_bags.reader import open_bag

    a, b = open_bag(args.a), open_bag(args.b)
    result = diff_bags(a, b, args.topics, args.tolerance)
    if args.json:
        print(json.dumps(result))
    else:
        print("\n".join(diff_lines(result)))
    return 0 if result["same"] else 1


def cmd_info(args: argparse.Namespace) -> int:
    """``ant-bag info``."""
    from excavation_bags.metadata import latched
    from excavation_bags.reader import open_bag, topic_sizes

    bag = open_bag(args.bag)
    sizes = topic_sizes(bag) if args.sizes else {}
    print(f"bag:       {bag.path}")
    print(f"file:      {bag.mcap.name} ({bag.size_bytes} bytes)")
    print(f"producer:  {bag.producer or 'unknown'}   ros_distro: {bag.ros_distro or 'unknown'}")
    print(f"duration:  {bag.duration_s:.3f} s   size: {size_per_minute(bag)}")
    print(f"messages:  {bag.message_count}" + ("   TRUNCATED" if bag.truncated else ""))
    width = max((len(t) for t in bag.topics), default=5)
    for t in bag.topics.values():
        flag = "latched" if latched(t.qos) else ""
        size = f"{sizes[t.name] / 1e6:>9.3f} MB  " if args.sizes else ""
        print(f"  {t.name:<{width}}  {t.msgtype:<45} {t.count:>7}  {size}{flag}")
    for w in bag.warnings:
        print(f"warning: {w}")
    return 0


def cmd_recover(args: argparse.Namespace) -> int:
    """``ant-bag recover``."""
    from excavation_bags.reader import open_bag
    from excavation_bags.recover import recover_bag

    bag = open_bag(args.bag)
    new = recover_bag(args.bag, args.out)
    state = f"truncated ({bag.truncated})" if bag.truncated else "complete"
    print(f"ant-bag: {args.bag} was {state}; wrote {new.message_count} messages to {args.out}")
    return 0


def cmd_report(args: argparse.Namespace) -> int:
    """``ant-bag report``."""
    from excavation_bags.reader import open_bag
    from excavation_bags.report import make_report

    bag = open_bag(args.bag)
    report = make_report(
        bag, args.out, args.height_unit, gif=not args.no_gif, gif_stride=args.gif_stride
    )
    for w in report.warnings:
        print(f"ant-bag: warning: {w}", file=sys.stderr)
    for section, why in report.skipped.items():
        print(f"ant-bag: skipped {section}: {why}", file=sys.stderr)
    print(f"ant-bag: report in {report.out}: {', '.join(report.files)}")
    return 0


SITE_HELP = "take the domain and discovery range from this site file (as ant-dome up does)"


def parser() -> argparse.ArgumentParser:
    """The command line."""
    p = argparse.ArgumentParser(
        prog="ant-bag",
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="\n\n".join(__doc__.split("\n\n")[1:3]),
    )
    sub = p.add_subparsers(dest="command", required=True)

    r = sub.add_parser("record", help="record topics into a new bag directory")
    r.add_argument("--out", required=True, metavar="DIR")
    r.add_argument("--topics", nargs="+", metavar="TOPIC", help="names or globs (default: suite)")
    r.add_argument("--duration", type=float, default=None, metavar="S")
    r.add_argument("--flush-period", type=float, default=None, metavar="S", help="default 0.5")
    r.add_argument("--height-unit", type=float, default=None, metavar="M", help="default 0.05")
    r.add_argument(
        "--image-codec",
        choices=("jpeg", "png", "none"),
        default=None,
        help="how raw camera frames are stored (default jpeg; png is lossless; none: raw)",
    )
    r.add_argument("--domain", type=int, default=None)
    r.add_argument(
        "--site",
        metavar="SITE",
        help="take the domain and discovery range from this site file (as ant-dome up does)",
    )
    r.set_defaults(run=cmd_record)

    pl = sub.add_parser("play", help="republish a bag")
    pl.add_argument("bag", metavar="DIR")
    pl.add_argument("--rate", type=float, default=None, help="default 1.0")
    pl.add_argument("--topics", nargs="+", metavar="TOPIC")
    pl.add_argument("--loop", action="store_true")
    pl.add_argument("--delay", type=float, default=None, metavar="S", help="default 0.5")
    pl.add_argument("--lockstep", action="store_true", help="tick by tick, waiting for replies")
    pl.add_argument("--wait-for", nargs="+", metavar="TOPIC")
    pl.add_argument(
        "--clock",
        type=float,
        nargs="?",
        const=40.0,
        default=None,
        metavar="HZ",
        help="publish /clock from the bag's time (default 40 Hz), for nodes on use_sim_time",
    )
    pl.add_argument("--start-offset", type=float, default=None, metavar="S", help="start S s in")
    pl.add_argument("--exclude", nargs="+", metavar="TOPIC", help="names or globs not to play")
    pl.add_argument("--quiet", action="store_true", help="no progress line")
    who = pl.add_mutually_exclusive_group()
    who.add_argument(
        "--genome",
        metavar="FILE",
        help="tick replay: fresh controllers with this genome decide every recorded tick "
        "again; reports the ticks whose words differ (exit 1 if any)",
    )
    who.add_argument("--hand-coded", action="store_true", help="tick replay with the rules")
    pl.add_argument("--height-unit", type=float, default=0.05, metavar="M", help="tick replay")
    pl.add_argument(
        "--tick-timeout", type=float, default=30.0, metavar="S", help="tick replay: wait per tick"
    )
    pl.add_argument("--show", type=int, default=20, metavar="N", help="differing words shown")
    pl.add_argument("--json", action="store_true", help="tick replay: the comparison as JSON")
    who.add_argument(
        "--reperceive",
        action="store_true",
        help="play the sensor topics into a fresh localiser and mapper; record their poses "
        "and height maps into --out",
    )
    pl.add_argument("--out", metavar="DIR", help="re-perception: the bag it records")
    pl.add_argument("--run-dir", metavar="RUN", help="re-perception: ant-dome's run directory")
    pl.add_argument("--localizer-params", metavar="FILE", help="re-perception: instead of RUN's")
    pl.add_argument("--mapper-params", metavar="FILE", help="re-perception: instead of RUN's")
    pl.add_argument("--domain", type=int, default=None)
    pl.add_argument(
        "--site",
        metavar="SITE",
        help="take the domain and discovery range from this site file (as ant-dome up does)",
    )
    pl.set_defaults(run=cmd_play)

    d = sub.add_parser("diff", help="two bags compared topic by topic (exit 1 if they differ)")
    d.add_argument("a", metavar="A")
    d.add_argument("b", metavar="B")
    d.add_argument("--topics", nargs="+", metavar="TOPIC", help="names or globs (default: all)")
    d.add_argument(
        "--tolerance", type=float, default=1e-6, help="height map cells: a difference above it"
    )
    d.add_argument("--json", action="store_true")
    d.set_defaults(run=cmd_diff)

    i = sub.add_parser("info", help="topics, counts and QoS of a bag")
    i.add_argument("bag", metavar="DIR")
    i.add_argument("--sizes", action="store_true", help="message bytes per topic (reads all)")
    i.set_defaults(run=cmd_info)

    rc = sub.add_parser("recover", help="write a complete copy of a truncated bag")
    rc.add_argument("bag", metavar="DIR")
    rc.add_argument("--out", required=True, metavar="DIR")
    rc.set_defaults(run=cmd_recover)

    rp = sub.add_parser("report", help="figures and a summary of a recorded trial")
    rp.add_argument("bag", metavar="DIR")
    rp.add_argument("--out", required=True, metavar="DIR")
    rp.add_argument("--height-unit", type=float, default=None, metavar="M")
    rp.add_argument("--no-gif", action="store_true")
    rp.add_argument("--gif-stride", type=int, default=None, metavar="N")
    rp.set_defaults(run=cmd_report)
    return p


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``ant-bag`` (also ``ros2 run excavation_bags ant-bag``)."""
    from rclpy.utilities import remove_ros_args

    argv = sys.argv[1:] if argv is None else argv
    args = parser().parse_args(remove_ros_args(["ant-bag", *argv])[1:])
    args.ros_args = argv[argv.index("--ros-args") :] if "--ros-args" in argv else []
    try:
        if getattr(args, "site", None):
            from excavation_common.network import use_site_network

            use_site_network(args.site)
        return args.run(args)
    except (FieldError, ValueError, OSError) as exc:
        print(f"ant-bag: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
