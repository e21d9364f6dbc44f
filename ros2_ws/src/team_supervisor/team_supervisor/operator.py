"""``ant-operator``: the operator's command line for the team (there is no ros2cli here).

::

    ant-operator status                  # team state and every robot's
    ant-operator estop                   # latch the e-stop: every robot stops
    ant-operator reset                   # clear the e-stop (the team is then disarmed)
    ant-operator arm                     # allow motion
    ant-operator pause / resume          # stop every robot / carry on
    ant-operator disable 2 / enable 2    # take robot 2 out of the team / back in
    ant-operator drive 1 0.1 0.0 --for 2 # override robot 1's wheels for 2 s (10 Hz)
    ant-operator blade 1 0.05 --for 1    # override robot 1's blade set-point (m) for 1 s
    ant-operator console --robots 4      # stay connected: keys for all of the above

Every command talks to the supervisor's services (``/supervisor/...``, ``--supervisor``) or
to a robot's override topic, on ``--domain`` (default ``ROS_DOMAIN_ID``) and, unless set
already, ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``. Exit codes: 0 done, 1 the supervisor
refused (its reason is printed), 2 bad arguments, 3 nobody answered within ``--timeout``
(no supervisor, or no node subscribes to the override topic). Behaviour of each command:
docs/operator.md. A ROS-level stop is not a safety function: the dome needs a hardware
e-stop on motor power.
"""

from __future__ import annotations

import argparse
import os
import sys

from team_supervisor.client import NoAnswer, Operator

EXIT_OK, EXIT_REFUSED, EXIT_USAGE, EXIT_NO_ANSWER = 0, 1, 2, 3
TRIGGERS = ("status", "estop", "reset", "arm", "pause", "resume")


def parser() -> argparse.ArgumentParser:
    """The ``ant-operator`` argument parser."""
    p = argparse.ArgumentParser(prog="ant-operator", description=__doc__.split("\n\n")[0])
    p.add_argument("--domain", type=int, default=None, help="ROS domain (default ROS_DOMAIN_ID)")
    p.add_argument(
        "--site",
        metavar="SITE",
        help="take the domain and discovery range from this site file (as ant-dome up does)",
    )
    p.add_argument("--supervisor", default="/supervisor", help="the supervisor node's name")
    p.add_argument("--timeout", type=float, default=5.0, help="s to wait for an answer")
    sub = p.add_subparsers(dest="command", required=True)
    for name in TRIGGERS:
        sub.add_parser(name, help=f"the supervisor's ~/{name}")
    for name in ("enable", "disable"):
        sub.add_parser(name, help=f"{name} one robot").add_argument("robot", type=int)
    drive = sub.add_parser("drive", help="override one robot's wheels (needs its executor)")
    drive.add_argument("robot", type=int)
    drive.add_argument("vx", type=float, help="forward speed, m/s")
    drive.add_argument("wz", type=float, help="turn rate, rad/s (counter-clockwise)")
    drive.add_argument("--for", dest="seconds", type=float, required=True, help="seconds")
    blade = sub.add_parser("blade", help="override one robot's blade set-point")
    blade.add_argument("robot", type=int)
    blade.add_argument("position", type=float, help="blade set-point, m (home 0.10)")
    blade.add_argument("--for", dest="seconds", type=float, default=1.0, help="seconds (1)")
    console = sub.add_parser(
        "console", help="stay connected: keys for e-stop, arm, pause, driving a robot, ..."
    )
    console.add_argument("--robots", type=int, default=4, help="robots in the team (4)")
    return p


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``ant-operator``."""
    args = parser().parse_args(argv)
    if getattr(args, "seconds", 1.0) <= 0 or args.timeout <= 0:
        print("ant-operator: error: --for and --timeout must be > 0", file=sys.stderr)
        return EXIT_USAGE
    if getattr(args, "robots", 1) < 1:
        print(f"ant-operator: error: --robots {args.robots}: must be >= 1", file=sys.stderr)
        return EXIT_USAGE
    if getattr(args, "robot", 0) < 0:
        print(f"ant-operator: error: robot {args.robot}: must be >= 0", file=sys.stderr)
        return EXIT_USAGE
    if args.site:
        from excavation_common.errors import FieldError
        from excavation_common.network import use_site_network

        try:
            use_site_network(args.site)
        except FieldError as exc:
            print(f"ant-operator: error: {exc}", file=sys.stderr)
            return EXIT_USAGE
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    domain = args.domain if args.domain is not None else int(os.environ.get("ROS_DOMAIN_ID", "0"))
    op = Operator(domain, args.supervisor, args.timeout)
    try:
        if args.command == "console":
            from team_supervisor.console_node import console_main

            return console_main(op, args.robots)
        if args.command in TRIGGERS:
            ok, message = op.trigger(args.command)
        elif args.command in ("enable", "disable"):
            ok, message = op.enable(args.robot, args.command == "enable")
        elif args.command == "drive":
            n = op.drive(args.robot, args.vx, args.wz, args.seconds)
            ok, message = True, f"robot {args.robot}: {n} drive overrides sent, the last one zero"
        else:
            n = op.blade(args.robot, args.position, args.seconds)
            ok, message = True, f"robot {args.robot}: {n} blade set-points {args.position:g} m sent"
        if args.command != "status":  # an action: its origin goes to ant-dome's events log
            what = " ".join([args.command, *([str(args.robot)] if hasattr(args, "robot") else [])])
            op.announce(f"{what} from the command line: {'done' if ok else 'refused'}: {message}")
    except NoAnswer as exc:
        print(f"ant-operator: error: {exc}", file=sys.stderr)
        return EXIT_NO_ANSWER
    except KeyboardInterrupt:
        return EXIT_REFUSED
    finally:
        op.close()
    if not ok:
        print(f"ant-operator: refused: {message}", file=sys.stderr)
        return EXIT_REFUSED
    print(message)
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
