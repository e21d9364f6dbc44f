"""``ant-dome rehearse SITE`` with robots on their own hosts: every host in its namespace.

The rehearsal makes one network namespace per host of the site
(:class:`~excavation_bringup.virtual_hosts.VirtualHosts`), then runs ``ant-dome rehearse``
again inside the dome PC's namespace (``--netns TAG``), which starts the whole graph as
usual, each robot host's share through ``ip netns exec`` into that host's namespace: the
processes of different hosts reach each other only across the virtual links, by unicast to
the site's static peers. When the inner run ends (or Ctrl-C), the namespaces go. With
``--view`` the view's port on the dome PC's loopback is forwarded to this machine's
(:mod:`excavation_bringup.port_forward`), so Foxglove connects as in any other mode.

A drill (``--drop-link HOST:AFTER:FOR``) takes robot host ``HOST``'s link down ``AFTER``
seconds after the team is armed, for ``FOR`` seconds, then up again, and re-arms the team
:data:`REARM_AFTER` seconds later, as an operator would once the robot's stop was seen.
``--kill-host HOST:AFTER`` instead SIGKILLs the processes of ``HOST``'s share (its robots'
executors and blade drivers; the emulated base and board are the robot's hardware and stay)
``AFTER`` seconds after the arming, as a crashed robot computer would lose them; ``ant-dome``
restarts them. ``--clock-offset HOST:SECONDS`` runs every process of ``HOST``'s share with its
wall clock ``SECONDS`` off the dome PC's from the start (libfaketime's ``LD_PRELOAD`` library
shifts ``CLOCK_REALTIME`` only; a robot computer that never synchronised its clock). A
recorder on that host (``RUN/robot_bags/HOST``) keeps what the robot's own nodes did
meanwhile, and ``RUN/drill.json`` the drill's times (wall clock, as the bags' stamps) and
what the robot-side bag shows: when its wheels and blade stopped after the fault, and
whether anything moved between the link's return and the re-arm.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

from excavation_bringup import site as sitefile
from excavation_bringup.port_forward import NamespaceForward
from excavation_bringup.virtual_hosts import VirtualHosts, VirtualHostsError

REARM_AFTER = 3.0
"""Seconds after a drill's link returns that the operator re-arms (the robot stands still)."""


def parse_drop(text: str) -> tuple[str, float, float]:
    """``HOST:AFTER:FOR`` -> ``(host, after s, for s)``.

    Raises:
        ValueError: Not three fields, or a time that is not a positive number.
    """
    parts = text.split(":")
    if len(parts) != 3:
        raise ValueError(f"--drop-link {text!r}: expected HOST:AFTER:FOR (seconds)")
    host, after, span = parts[0], float(parts[1]), float(parts[2])
    if not (after >= 0 and span > 0):
        raise ValueError(f"--drop-link {text!r}: AFTER >= 0 and FOR > 0 seconds")
    return host, after, span


def parse_kill(text: str) -> tuple[str, float, float]:
    """``HOST:AFTER`` -> ``(host, after s, 0.0)``.

    Raises:
        ValueError: Not two fields, or a time that is not a number >= 0.
    """
    parts = text.split(":")
    if len(parts) != 2:
        raise ValueError(f"--kill-host {text!r}: expected HOST:AFTER (seconds)")
    after = float(parts[1])
    if not after >= 0:
        raise ValueError(f"--kill-host {text!r}: AFTER >= 0 seconds")
    return parts[0], after, 0.0


def parse_offset(text: str) -> tuple[str, float, float]:
    """``HOST:SECONDS`` -> ``(host, seconds, 0.0)``; ``SECONDS`` may be negative (behind).

    Raises:
        ValueError: Not two fields, or an offset that is zero, not finite or over an hour.
    """
    parts = text.split(":")
    if len(parts) != 2:
        raise ValueError(f"--clock-offset {text!r}: expected HOST:SECONDS")
    try:
        offset = float(parts[1])
    except ValueError:
        raise ValueError(f"--clock-offset {text!r}: SECONDS is not a number") from None
    if not (0.0 < abs(offset) <= 3600.0):
        raise ValueError(f"--clock-offset {text!r}: SECONDS non-zero, at most 3600 either way")
    return parts[0], offset, 0.0


def clock_prefix(offset: float) -> list[str]:
    """The ``env`` words that run a process with its wall clock ``offset`` s off.

    libfaketime's library, preloaded, shifts ``CLOCK_REALTIME`` (Python's ``time.time``,
    the ROS clock, DDS source stamps) and leaves the monotonic clocks (timers, timeouts) as
    they are, as an unsynchronised computer's clocks would be.

    Raises:
        VirtualHostsError: The library is not where the ``libfaketime`` package says.
    """
    import libfaketime

    _, extra = libfaketime.get_reload_information()
    library = Path(extra["LD_LIBRARY_PATH"]) / extra["LD_PRELOAD"].split(":")[0]
    if not library.is_file():
        raise VirtualHostsError(f"--clock-offset: libfaketime's library {library} is missing")
    preload = ":".join(p for p in (str(library), os.environ.get("LD_PRELOAD", "")) if p)
    # The package's own settings (monotonic clocks left alone; FAKETIME_FORCE_MONOTONIC_FIX=0,
    # without which timed waits on monotonic condition variables, Python's GIL among them,
    # run late: a thread waited 50-100 ms for the GIL), less its LD_LIBRARY_PATH.
    settings = {k: v for k, v in extra.items() if k not in ("LD_PRELOAD", "LD_LIBRARY_PATH")}
    return [
        "env",
        f"LD_PRELOAD={preload}",
        *(f"{k}={v}" for k, v in sorted(settings.items())),
        "FAKETIME_DONT_FAKE_MONOTONIC=1",
        f"FAKETIME={offset:+.6f}",
    ]


def _tag() -> str:
    """A short tag, unique among the rehearsals running on this machine (the pid)."""
    return f"{os.getpid() % 1_000_000}"


def robot_topics(site: sitefile.Site, host: str) -> list[str]:
    """What a robot host's recorder keeps: its robots' drives, wheels, blades, team state."""
    topics = ["/team/heartbeat", "/team/armed", "/team/estop", "/diagnostics"]
    for k, robot in enumerate(site.robots):
        if site.robot_host(k) == host:
            ns = f"/robot_{k}"
            topics += [
                robot.drive_topic_resolved,
                f"/sim{ns}/cmd_vel",
                f"{ns}/blade/joint_states",
                f"{ns}/drive/status",
            ]
    return topics


class Drill:
    """A fault on a robot host (a thread), with a robot-side recorder meanwhile.

    ``kind`` ``drop``: the link down, up, re-arm; ``kill``: the host's nodes SIGKILLed;
    ``clock``: nothing more (the host's clock runs off from the start). The recorder runs on
    the host's clock too, as any process there would: Fast DDS's shared-memory transport
    between processes of one host stalled delivery for up to 0.6 s while participants were
    discovered when their clocks differed by a second, which no real host has.
    """

    def __init__(
        self, hosts: VirtualHosts, site, run_dir: Path, domain: int, drop, echo, kind="drop"
    ):
        self.hosts, self.site, self.run_dir, self.domain = hosts, site, run_dir, domain
        self.host, self.after, self.span = drop
        self.kind = kind
        self.echo = echo
        self.times: dict[str, float] = {}
        self.recorder: subprocess.Popen | None = None
        self.bag = run_dir / "robot_bags" / self.host
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="ant-dome-drill", daemon=True)

    def start(self) -> None:
        """Begin (waits for the arming in the run's events)."""
        self._thread.start()

    def stop(self) -> None:
        """End the drill and its recorder."""
        self._stop.set()
        self._thread.join(timeout=60.0)
        if self.recorder is not None and self.recorder.poll() is None:
            self.recorder.send_signal(signal.SIGINT)
            try:
                self.recorder.wait(timeout=30)
            except subprocess.TimeoutExpired:
                self.recorder.kill()
                self.recorder.wait()

    def _armed(self) -> bool:
        events = self.run_dir / "events.log"
        return events.exists() and "armed the team" in events.read_text(errors="replace")

    def _operator(self, command: str) -> str:
        cmd = self.hosts.prefix(self.site.dome_host) + [
            sys.executable,
            "-m",
            "team_supervisor.operator",
            "--domain",
            str(self.domain),
            command,
        ]
        result = subprocess.run(cmd, capture_output=True, text=True, timeout=60)
        return (result.stdout + result.stderr).strip()

    def _run(self) -> None:
        while not self._stop.is_set() and not self._armed():
            self._stop.wait(0.5)
        if self._stop.is_set():
            return
        self.bag.parent.mkdir(parents=True, exist_ok=True)
        on_host_clock = clock_prefix(self.after) if self.kind == "clock" else []
        self.recorder = subprocess.Popen(
            self.hosts.prefix(self.host)
            + on_host_clock
            + [sys.executable, "-m", "excavation_bags.cli", "record", "--out", str(self.bag)]
            + ["--domain", str(self.domain), "--topics", *robot_topics(self.site, self.host)],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            start_new_session=True,
        )
        self.times["armed"] = time.time()
        if self.kind == "clock" or self._stop.wait(self.after):
            return
        if self.kind == "kill":
            self._kill()
            return
        self.hosts.set_link(self.host, False)
        self.times["link_down"] = time.time()
        self.echo(f"drill: {self.host}'s link down")
        self._stop.wait(self.span)
        self.hosts.set_link(self.host, True)
        self.times["link_up"] = time.time()
        self.echo(f"drill: {self.host}'s link up")
        if self._stop.wait(REARM_AFTER):
            return
        self.times["rearm"] = time.time()
        self.echo(f"drill: re-arm: {self._operator('arm')}")

    def _kill(self) -> None:
        """SIGKILL the host's share (from the run's ``state.json``), as a crash would."""
        state = json.loads((self.run_dir / "state.json").read_text())
        robots = [k for k in range(self.site.n_robots) if self.site.robot_host(k) == self.host]
        self.times["killed"] = time.time()
        for k in robots:
            for name in (f"executor_{k}", f"blade_driver_{k}"):
                pid = (state.get(name) or {}).get("pid")
                if pid:
                    try:
                        os.kill(int(pid), signal.SIGKILL)
                    except ProcessLookupError:
                        continue
                    self.echo(f"drill: killed {name} (pid {pid}) on {self.host}")

    def report(self) -> dict:
        """The drill's times and what the robot-side bag shows (``RUN/drill.json``)."""
        if self.kind == "clock":
            out: dict = {"host": self.host, "kind": "clock", "offset": self.after} | self.times
            if self.bag.exists() and "armed" in self.times:
                # the bag's stamps are on the host's clock
                armed = self.times["armed"] + self.after
                out |= clock_side(self.bag, self.site, self.host, armed)
            return out
        out = {"host": self.host, "kind": self.kind, "after": self.after} | self.times
        if self.kind == "drop":
            out["for"] = self.span
        start = "link_down" if self.kind == "drop" else "killed"
        if self.bag.exists() and start in self.times:
            out |= robot_side(self.bag, self.site, self.host, self.times, start)
        return out


def robot_side(
    bag: Path, site, host: str, times: dict[str, float], start: str = "link_down"
) -> dict:
    """From a robot host's bag: what its robots did after a fault.

    When the drive and the wheels were first at zero and the blade home after
    ``times[start]``, and how many non-zero commands came between the link's return and
    the re-arm (a dropped link).
    """
    from excavation_bags.reader import open_bag

    b = open_bag(bag)
    down, up = times[start], times.get("link_up")
    rearm = times.get("rearm")
    robots = [k for k in range(site.n_robots) if site.robot_host(k) == host]
    result: dict = {}
    for k in robots:
        wheels, drive = f"/sim/robot_{k}/cmd_vel", site.robots[k].drive_topic_resolved
        blade = f"/robot_{k}/blade/joint_states"
        first_zero: dict[str, float] = {}
        moved_before_rearm = 0
        blade_home = None
        for topic, t_ns, raw in b.messages([wheels, drive, blade]):
            t = t_ns * 1e-9
            if t < down:
                continue
            msg = b.decode(topic, raw)
            if topic == blade:
                if blade_home is None and abs(msg.position[0] - 0.10) < 0.005:
                    blade_home = t - down
                continue
            tw = msg.twist if hasattr(msg, "twist") else msg
            zero = tw.linear.x == 0.0 and tw.angular.z == 0.0
            if zero and topic not in first_zero:
                first_zero[topic] = t - down
            if up is not None and up <= t and (rearm is None or t < rearm) and not zero:
                moved_before_rearm += 1
        result[f"robot_{k}"] = {
            "drive_zero_after_fault_s": first_zero.get(drive),
            "wheels_zero_after_fault_s": first_zero.get(wheels),
            "blade_home_after_fault_s": blade_home,
            "non_zero_commands_between_link_up_and_rearm": moved_before_rearm,
        }
    return result


def clock_side(bag: Path, site, host: str, armed: float) -> dict:
    """From a robot host's bag: how its robots drove with the host's clock off.

    Per robot, after the arming: drive commands and wheel commands sent (and how many were
    not zero), and each distinct message its executor and blade driver put on
    ``/diagnostics`` (what an operator reads to find the cause).
    """
    from excavation_bags.reader import open_bag

    b = open_bag(bag)
    robots = [k for k in range(site.n_robots) if site.robot_host(k) == host]
    result: dict = {}
    for k in robots:
        wheels, drive = f"/sim/robot_{k}/cmd_vel", site.robots[k].drive_topic_resolved
        counts = {drive: [0, 0], wheels: [0, 0]}
        said: dict[str, list[str]] = {}
        for topic, t_ns, raw in b.messages([wheels, drive, "/diagnostics"]):
            if t_ns * 1e-9 < armed:
                continue
            msg = b.decode(topic, raw)
            if topic == "/diagnostics":
                for status in msg.status:
                    level = status.level
                    level = level[0] if isinstance(level, bytes) else int(level)
                    if f"robot_{k}" in status.name and level > 0:
                        seen = said.setdefault(status.name, [])
                        text = _without_numbers(status.message)
                        if text not in (_without_numbers(m) for m in seen):
                            seen.append(status.message)
                continue
            tw = msg.twist if hasattr(msg, "twist") else msg
            counts[topic][0] += 1
            counts[topic][1] += int(tw.linear.x != 0.0 or tw.angular.z != 0.0)
        result[f"robot_{k}"] = {
            "drive_commands": counts[drive][0],
            "drive_commands_not_zero": counts[drive][1],
            "wheel_commands": counts[wheels][0],
            "wheel_commands_not_zero": counts[wheels][1],
            "diagnostics": said,
        }
    return result


def _without_numbers(text: str) -> str:
    """``text`` with its numbers blanked (one message per kind, not per value)."""
    import re

    return re.sub(r"-?\d+(\.\d+)?", "#", text)


def rehearse_hosts(args, site: sitefile.Site, argv: list[str]) -> int:
    """The outer run: namespaces, the inner ``ant-dome`` in the dome PC's, the drill."""
    drop, kind = None, "drop"
    drills = {
        "drop": ("--drop-link", args.drop_link, parse_drop),
        "kill": ("--kill-host", args.kill_host, parse_kill),
        "clock": ("--clock-offset", args.clock_offset, parse_offset),
    }
    for name, (option, value, parse) in drills.items():
        if not value:
            continue
        kind = name
        try:
            drop = parse(value)
            if kind == "clock":
                clock_prefix(drop[1])
        except (ValueError, VirtualHostsError) as exc:
            print(f"ant-dome: error: {exc}", file=sys.stderr)
            return 2
        robot_hosts = [h.name for h in site.hosts[1:]]
        if drop[0] not in robot_hosts:
            print(
                f"ant-dome: error: {option} {drop[0]}: not a robot host ({robot_hosts})",
                file=sys.stderr,
            )
            return 2
    hosts = VirtualHosts([(h.name, h.address) for h in site.hosts], _tag())
    try:
        hosts.create()
    except VirtualHostsError as exc:
        print(f"ant-dome: error: {exc}", file=sys.stderr)
        return 2
    run_dir = Path(args.run_dir).resolve()
    run_dir.mkdir(parents=True, exist_ok=True)
    domain = args.domain if args.domain is not None else site.network.domain
    inner = hosts.prefix(site.dome_host) + [
        sys.executable,
        "-m",
        "excavation_bringup.dome",
        *argv,
        "--run-dir",
        str(run_dir),
        "--netns",
        hosts.tag,
    ]
    echo = (lambda text: None) if args.json else (lambda text: print(f"ant-dome: {text}"))
    echo(
        "hosts: "
        + ", ".join(f"{h.name} {h.address} (namespace {h.namespace})" for h in hosts.hosts)
    )
    forward = None
    if args.view:  # the view binds the dome PC's loopback: bring its port to this one's
        try:
            forward = NamespaceForward(hosts.prefix(site.dome_host), args.view_port)
        except OSError as exc:
            hosts.remove()
            print(f"ant-dome: error: --view-port {args.view_port}: {exc}", file=sys.stderr)
            return 2
        forward.start()
        echo(f"live view: ws://127.0.0.1:{args.view_port} (forwarded from host dome)")
    proc = subprocess.Popen(inner, start_new_session=True)
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda s, _f: proc.send_signal(s))
    drill = Drill(hosts, site, run_dir, domain, drop, echo, kind) if drop else None
    try:
        if drill is not None:
            drill.start()
        code = proc.wait()
    finally:
        if drill is not None:
            drill.stop()
            report = drill.report()
            (run_dir / "drill.json").write_text(json.dumps(report, indent=1))
            echo(f"drill: {json.dumps(report)}")
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        if forward is not None:
            forward.stop()
        hosts.remove()
    return code
