"""``ant-dome``: check a site file, and bring the dome up from it (paper, 6).

``ant-dome check SITE [--sim]`` prints every inconsistency of a site file
(:mod:`excavation_bringup.site`), one per line as ``file: field = value: reason``, and
exits 1 if there is any.

``ant-dome plan SITE [--sim | --rehearse]`` prints each host's share of the graph (the
nodes ``ant-dome up SITE --host NAME`` starts there, in start order) and the network every
process gets. A site with robots on their own computers (``hosts``, ``robots[k].host``)
runs ``ant-dome up SITE --host NAME`` on each: a robot's host runs its drive executor and
blade driver (the parts that must stop the robot when its link drops), the dome PC (the
first host) everything else, the supervisor first. Without ``--host`` every node runs here.

``ant-dome up SITE [--sim] [--record BAG] [--view]`` generates every node's parameters from
the site file and starts each node as its own process (the venv's interpreter, ``python -m
module``, as ``ros2 run`` would), in the order of the trial graph
(:func:`excavation_bringup.graph.continuous`), each one only after the one before it has
reported on ``/diagnostics``. A node that crashes is restarted with exponential back-off and
reported; a node that exits with code 2 (a bad parameter or file: it would fail again),
exhausts its restarts or is not restartable ends the run. Every node logs into
``RUN/logs/NAME.log``; ``RUN/events.log`` has the supervisor's reports and
``RUN/state.json`` each node's pid, state and restarts. Ctrl-C (SIGINT) or SIGTERM stops the
nodes one by one in reverse order (the bag recorder, started first, stops last and finishes
the bag).

In the dome (no ``--sim``) the table is the hardware's: the team supervisor first,
DISARMED (nothing moves until ``ant-operator arm``), the blueprint server, the localiser and
the mapper on the site's camera and laser, one blade driver per robot on its board (a tick's
blade bits after the tick's drive: ``blade_after_motion``), one drive executor per robot
(closing its loop on the localiser's ``/robot_k/pose``, its ``cmd_vel`` remapped to the
robot's ``drive_topic``: the base), the controllers (lockstep, on the team tick's ``/tick``
topics) and the team tick, which turns their words into goals for the executors, robot by
robot, and runs until Ctrl-C (``--ticks N``: N ticks, then the run ends). Every node runs on
the wall clock.

``--sim`` puts the continuous-motion simulator in place of the dome's hardware: the graph
of ``ant-trial --drive continuous --perception full --processes`` (the same graph function,
with the site's topics, offsets and LED table): ``dynamics`` (the
robots' bases and the clock: every other node runs on ``use_sim_time``), one drive
executor per robot closing its loop on the simulator's truth, the synthetic camera and
laser (``sensors``, rendering the simulator's snapshot after each tick's motion), the
simulator as every robot's blade board (the blade drivers' ``sim`` backend), and the team
tick, which runs the site's ticks (``--ticks``) and ends the run; the localizer and the
mapper see only the synthetic sensors. The fitness is printed.

Examples::

    ant-dome check ros2_ws/src/excavation_bringup/config/site_dome.yaml
    ant-dome up ros2_ws/src/excavation_bringup/config/site_sim.yaml --sim --view
    ant-dome up my_dome.yaml --record bags/trial_01 --view
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys
import threading
import time
from pathlib import Path

from excavation_bringup import site as sitefile
from excavation_bringup.deployment import Deployment
from excavation_bringup.graph import Graph, GraphError, continuous
from excavation_bringup.launch import ProcessLauncher
from excavation_bringup.nodes import RunFiles


def dome_graph(
    site: sitefile.Site,
    run_dir: Path,
    hardware: str = "dome",
    record: str | None = None,
    view: bool = False,
    ticks: int | None = None,
    view_port: int = 8765,
    domain: int | None = None,
    check: bool = True,
) -> Graph:
    """Every process of the dome, in start order (stopped in reverse).

    ``hardware``: ``dome`` (``up``), ``sim`` (``up --sim``) or ``emulated`` (``rehearse``).
    Writes the files the nodes read into ``run_dir`` (the site's LED table, and with a
    ``simulated`` calibration the synthetic camera's model).

    Raises:
        excavation_bringup.graph.GraphError: ``check`` and a node would refuse its
            parameters (the site's ``overrides:``); without ``check`` the graph is returned
            and :meth:`~excavation_bringup.graph.Graph.problems` lists them.
    """
    dep = Deployment.from_site(site, hardware, ticks, record, domain)
    dep.check()
    graph = continuous(dep, run_dir, view, view_port)
    return graph.check() if check else graph


def site_problems(path: str | Path, hardware: str = "dome") -> list[str]:
    """Every problem of site file ``path`` for ``hardware``, one line each (empty: usable).

    The site's own checks (:func:`excavation_bringup.site.check_site`), then, on the graph it
    would start, the nodes' parameters with the site's ``overrides:`` applied
    (:meth:`~excavation_bringup.graph.Graph.problems`) and the remappings
    (:func:`start_problems`).
    """
    import tempfile

    site, errors = sitefile.check_site(path, sim=hardware == "sim", emulated=hardware == "emulated")
    if errors:
        return [str(e) for e in errors]
    from excavation_common.params import ParameterError

    with tempfile.TemporaryDirectory(prefix="ant-dome-check-") as tmp:
        try:
            graph = dome_graph(site, Path(tmp), hardware, check=False)
        except ParameterError as exc:  # what the site sets breaks a rule of a node's own
            what = (
                exc.reason
                if exc.field == "parameters"
                else f"{exc.field} = {exc.value!r}: {exc.reason}"
            )
            return [f"{path}: node {exc.path} would refuse its parameters: {what}"]
    return [str(e) for e in graph.problems()] + start_problems(graph, str(path))


def cmd_plan(args: argparse.Namespace) -> int:
    """``ant-dome plan``: each host's share of the graph."""
    import tempfile

    hardware = "sim" if args.sim else "emulated" if args.rehearse else "dome"
    site, errors = sitefile.check_site(args.site, sim=args.sim, emulated=args.rehearse)
    try:
        if not errors:
            with tempfile.TemporaryDirectory(prefix="ant-dome-plan-") as tmp:
                graph = dome_graph(site, Path(tmp), hardware)
    except GraphError as exc:
        errors = exc.problems
    if errors:
        for e in errors:
            print(f"ant-dome: error: {e}", file=sys.stderr)
        return 2
    env = sitefile.environment(site)
    addresses = {h.name: h.address for h in site.hosts}
    shares = {host: [n.name for n in graph.share(host)] for host in graph.hosts}
    if args.json:
        print(
            json.dumps(
                {"hardware": hardware, "network": env, "hosts": addresses} | {"shares": shares}
            )
        )
        return 0
    print(f"ant-dome: {args.site}: {hardware} hardware, {len(graph.nodes)} nodes")
    for host, names in shares.items():
        role = "the dome PC" if host == graph.hosts[0] else "a robot's computer"
        print(f"host {host} ({addresses[host]}, {role}): {', '.join(names) or '-'}")
    print("network: " + " ".join(f"{k}={v}" for k, v in env.items()))
    return 0


def start_problems(graph: Graph, where: str) -> list[str]:
    """The remappings of ``graph`` a node would refuse at start, one line each.

    Every remapping's target must be a topic name; ``where`` (the site file) begins each
    line. (Every node's parameters went through its parameter classes' own checks when the
    graph was built: :class:`~excavation_bringup.node_params.NodeParams`.)
    """
    from excavation_common.topics import topic_name_problem

    out = []
    for spec in graph.nodes:
        for remap in spec.remaps:
            source, _, target = remap.partition(":=")
            problem = topic_name_problem(target)
            if problem:
                out.append(
                    f"{where}: node {spec.name}: remapping {source} to {target!r}: {problem}"
                )
    return out


def cmd_check(args: argparse.Namespace) -> int:
    """``ant-dome check``: the site's checks, then the nodes' start-up checks.

    The start-up checks run on the graph the site would start in the mode asked for
    (:func:`site_problems`).
    """
    hardware = "sim" if args.sim else "emulated" if args.rehearse else "dome"
    errors = site_problems(args.site, hardware)
    for e in errors:
        print(e)
    if errors:
        print(f"ant-dome: {len(errors)} problem(s) in {args.site}", file=sys.stderr)
        return 1
    site = sitefile.load_site(args.site, sim=args.sim, emulated=args.rehearse)
    hardware = "simulated" if args.sim else "emulated" if args.rehearse else "dome"
    print(
        f"ant-dome: {args.site} is consistent ({site.n_robots} robots, domain "
        f"{site.network.domain}, {hardware} hardware)"
    )
    return 0


def sim_result(run_dir: Path) -> dict | None:
    """A ``--sim`` run's result: the team tick's summary with the world's fitness and heights.

    ``None`` until the team tick has finished (or when the simulator wrote no world).
    """
    files = RunFiles(run_dir)
    ticks, world = files.result, files.world
    if not (ticks.exists() and world.exists()):
        return None
    data = json.loads(world.read_text())
    return json.loads(ticks.read_text()) | {"fitness": data["fitness"], "heights": data["heights"]}


class Arming:
    """A rehearsal's operator: arms the team once the supervisor answers (a thread).

    As a person would with ``ant-operator arm``: the dome's supervisor starts disarmed and
    nothing moves before it is armed. It asks every ``retry`` seconds until the
    supervisor agrees or the run ends.
    """

    def __init__(self, domain: int, report, retry: float = 2.0) -> None:
        self.domain = domain
        self.report = report
        self.retry = retry
        self.armed = False
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="ant-dome-arming", daemon=True)

    def start(self) -> None:
        """Begin asking."""
        self._thread.start()

    def stop(self) -> None:
        """Stop asking (the run ended)."""
        self._stop.set()
        self._thread.join(timeout=30.0)

    def _run(self) -> None:
        from team_supervisor.client import NoAnswer, Operator

        operator = Operator(self.domain, timeout=self.retry)
        try:
            while not self._stop.is_set():
                try:
                    ok, message = operator.trigger("arm")
                except NoAnswer:
                    ok, message = False, ""
                if ok:
                    self.armed = True
                    self.report(f"armed the team (as ant-operator arm): {message}")
                    return
                self._stop.wait(self.retry)
        finally:
            operator.close()


def bring_up(args: argparse.Namespace, hardware: str) -> int:
    """``ant-dome up`` (``dome`` or ``sim`` hardware) and ``ant-dome rehearse`` (``emulated``).

    A rehearsal of a site with robots on their own hosts (and no ``--host``) runs each host
    in a network namespace of its own (:mod:`excavation_bringup.host_rehearsal`).
    """
    errors = site_problems(args.site, hardware)
    if errors:
        for e in errors:
            print(f"ant-dome: error: {e}", file=sys.stderr)
        return 2
    site = sitefile.load_site(args.site, sim=hardware == "sim", emulated=hardware == "emulated")
    run_dir = Path(args.run_dir or Path("dome_runs") / time.strftime("%Y%m%d-%H%M%S")).resolve()
    several = hardware == "emulated" and len(site.hosts) > 1 and not args.host
    if several and not args.netns:
        from excavation_bringup.host_rehearsal import rehearse_hosts

        args.run_dir = str(run_dir)
        os.environ.update(sitefile.environment(site, args.domain))
        return rehearse_hosts(args, site, args.argv)
    record = str(Path(args.record).resolve()) if args.record else None
    graph = dome_graph(
        site, run_dir, hardware, record, args.view, args.ticks, args.view_port, args.domain
    )
    host = args.host or graph.hosts[0]
    try:
        graph.nodes = graph.share(host) if args.host else graph.nodes
    except KeyError as exc:
        print(f"ant-dome: error: --host {args.host}: {exc.args[0]}", file=sys.stderr)
        return 2
    on_dome_pc = host == graph.hosts[0]
    if not on_dome_pc and (record or args.view):
        print(
            f"ant-dome: error: --host {host}: --record and --view run on the dome PC "
            f"({graph.hosts[0]})",
            file=sys.stderr,
        )
        return 2
    # ant-dome's own nodes (the launcher watching /diagnostics, a rehearsal's operator) are
    # on the site's network too, not the shell's: a node on another host reports across it.
    os.environ.update(sitefile.environment(site, args.domain))
    env = dict(os.environ)
    prefixes: dict[str, list[str]] = {}
    clock_note = ""
    if several:  # inside the dome PC's namespace: each robot host's share in its own
        from excavation_bringup.virtual_hosts import VirtualHosts

        hosts = VirtualHosts([(h.name, h.address) for h in site.hosts], args.netns)
        prefixes = {n.name: hosts.prefix(n.host) for n in graph.nodes if n.host}
        if args.clock_offset:  # that host's processes on a clock off the dome PC's
            from excavation_bringup.host_rehearsal import clock_prefix, parse_offset

            off_host, offset, _ = parse_offset(args.clock_offset)
            clock_note = (
                f"drill: {off_host}'s processes run {offset:+.3f} s off the dome PC's clock"
            )
            for n in graph.nodes:
                if n.host == off_host:
                    prefixes[n.name] = prefixes[n.name] + clock_prefix(offset)
    dome = ProcessLauncher(graph, env, echo=not args.json, prefixes=prefixes)
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda s, _f: dome.request_stop(signal.Signals(s).name))
    dome.report(
        f"bringing up {args.site} ({len(graph.nodes)} nodes, domain {env['ROS_DOMAIN_ID']}) "
        f"in {run_dir}"
    )
    if clock_note:
        dome.report(clock_note)
    rehearsal_pc = hardware == "emulated" and on_dome_pc
    arming = Arming(int(env["ROS_DOMAIN_ID"]), dome.report) if rehearsal_pc else None
    if arming is not None:
        arming.start()
    try:
        ok = dome.run(timeout=args.timeout)
    finally:
        if arming is not None:
            arming.stop()
    result = sim_result(run_dir) if hardware != "dome" and on_dome_pc else None
    summary = {
        "ok": ok,
        "run_dir": str(run_dir),
        "failure": dome.supervisor.failure,
        "restarts": {c.name: c.restarts for c in dome.supervisor.children if c.restarts},
        "fitness": result["fitness"] if result else None,
        "ticks": len(result["commands"]) if result else None,
        "bag": record,
    }
    if args.json:
        print(json.dumps(summary))
    else:
        if result:
            print(f"ant-dome: fitness {result['fitness']:.4f} after {summary['ticks']} ticks")
        if record:
            print(f"ant-dome: bag {record} (ant-bag report {record} --out REPORT)")
        if not ok:
            print(f"ant-dome: failed: {dome.supervisor.failure}", file=sys.stderr)
    return 0 if ok else 1


def cmd_up(args: argparse.Namespace) -> int:
    """``ant-dome up``."""
    return bring_up(args, "sim" if args.sim else "dome")


def cmd_rehearse(args: argparse.Namespace) -> int:
    """``ant-dome rehearse``."""
    return bring_up(args, "emulated")


def parser() -> argparse.ArgumentParser:
    """The command line."""
    p = argparse.ArgumentParser(
        prog="ant-dome",
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="\n\n".join(__doc__.split("\n\n")[1:]),
    )
    sub = p.add_subparsers(dest="command", required=True)
    c = sub.add_parser("check", help="name every inconsistency of a site file")
    c.add_argument("site", metavar="SITE")
    how = c.add_mutually_exclusive_group()
    how.add_argument("--sim", action="store_true", help="check it for ant-dome up --sim")
    how.add_argument("--rehearse", action="store_true", help="check it for ant-dome rehearse")
    c.set_defaults(run=cmd_check)
    pl = sub.add_parser("plan", help="print each host's share of the graph and the network")
    pl.add_argument("site", metavar="SITE")
    how = pl.add_mutually_exclusive_group()
    how.add_argument("--sim", action="store_true", help="the graph of ant-dome up --sim")
    how.add_argument("--rehearse", action="store_true", help="the graph of ant-dome rehearse")
    pl.add_argument("--json", action="store_true", help="print it as JSON")
    pl.set_defaults(run=cmd_plan)
    u = sub.add_parser("up", help="bring the dome up from a site file")
    u.add_argument("--sim", action="store_true", help="the simulator in place of the hardware")
    r = sub.add_parser(
        "rehearse", help="the dome's table against emulated drivers, on the wall clock"
    )
    for q in (u, r):
        q.add_argument("site", metavar="SITE")
        q.add_argument("--record", metavar="BAG", help="record every suite topic into this bag")
        q.add_argument("--view", action="store_true", help="serve the live view (ant-view)")
        q.add_argument("--view-port", type=int, default=8765)
        q.add_argument(
            "--ticks",
            type=int,
            default=None,
            help="ticks to run (default: simulated or rehearsed the site's sim.ticks; the "
            "dome until Ctrl-C)",
        )
        q.add_argument("--domain", type=int, default=None, help="ROS domain (default: the site's)")
        q.add_argument("--run-dir", metavar="DIR", help="default dome_runs/<date-time>")
        q.add_argument("--timeout", type=float, default=None, help="give up after S seconds")
        q.add_argument("--json", action="store_true", help="print the outcome as JSON")
        q.add_argument(
            "--host",
            metavar="NAME",
            help="start only this host's share of the graph (ant-dome plan SITE lists them; "
            "default: every node here)",
        )
    u.set_defaults(run=cmd_up)
    drills = r.add_mutually_exclusive_group()
    drills.add_argument(
        "--drop-link",
        metavar="HOST:AFTER:FOR",
        help="robots on their own hosts: take HOST's link down AFTER s after arming, for FOR "
        "s, then re-arm (a drill; RUN/drill.json)",
    )
    drills.add_argument(
        "--kill-host",
        metavar="HOST:AFTER",
        help="robots on their own hosts: SIGKILL HOST's executors and blade drivers AFTER s "
        "after arming (a drill; RUN/drill.json)",
    )
    drills.add_argument(
        "--clock-offset",
        metavar="HOST:SECONDS",
        help="robots on their own hosts: run HOST's processes with the wall clock SECONDS off "
        "the dome PC's (negative: behind; a drill; RUN/drill.json)",
    )
    r.add_argument("--netns", default="", help=argparse.SUPPRESS)  # the inner run's tag
    u.set_defaults(netns="", drop_link=None, kill_host=None, clock_offset=None)
    r.set_defaults(run=cmd_rehearse)
    return p


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``ant-dome``."""
    argv = list(sys.argv[1:] if argv is None else argv)
    args = parser().parse_args(argv)
    args.argv = argv
    return args.run(args)


if __name__ == "__main__":
    sys.exit(main())
