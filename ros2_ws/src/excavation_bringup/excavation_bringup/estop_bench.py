"""``python -m excavation_bringup.estop_bench``: how long an e-stop takes from each console.

Starts a team supervisor and the live view as processes of their own (as ``ant-dome`` runs
them), then times, from the operator's action to the latched ``/team/estop`` arriving at a
watcher node (this process), ``repeats`` e-stops from each of:

* ``ant-operator estop``: the one-shot command (a new process each time): the reference;
* ``ant-operator console``: one process on a pseudo-terminal, the key written to it;
* the live view: a Foxglove WebSocket client (the protocol Foxglove speaks) calling
  ``/operator/estop``.

Between two e-stops the team is reset and armed again. Prints a Markdown table (median and
worst, and the reference's median over each console's); ``--write FILE`` puts it between
the ``<!-- estop-bench -->`` markers of FILE (``make bench``: docs/benchmarks.md). Runs on
ROS domain ``--domain`` with discovery on this machine.
"""

from __future__ import annotations

import argparse
import os
import pty
import select
import statistics
import subprocess
import sys
import time
from pathlib import Path

from excavation_interfaces.msg import TeamState

from excavation_bringup.view_client import ControlClient
from excavation_common.files import replace_marked

MARK = "<!-- estop-bench -->"


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Watcher:
    """A node that hears ``/team/estop`` and the heartbeat, and calls reset and arm."""

    def __init__(self, domain: int) -> None:
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from std_msgs.msg import Bool
        from std_srvs.srv import Trigger

        from excavation_common.ros import LATCHED

        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain)
        self.node = rclpy.create_node("estop_bench", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.estop: list[tuple[float, bool]] = []
        self.state = ""
        self.node.create_subscription(
            Bool, "/team/estop", lambda m: self.estop.append((time.monotonic(), m.data)), LATCHED
        )
        self.node.create_subscription(TeamState, "/team/heartbeat", self._beat, 10)
        self.clients = {
            n: self.node.create_client(Trigger, f"/supervisor/{n}") for n in ("reset", "arm")
        }

    def _beat(self, msg) -> None:
        self.state = msg.state

    def spin_until(self, condition, timeout: float = 60.0) -> bool:
        """Spin until ``condition()`` (False after ``timeout`` s)."""
        deadline = time.monotonic() + timeout
        while not condition():
            if time.monotonic() > deadline:
                return False
            self.executor.spin_once(timeout_sec=0.001)
        return True

    def call(self, name: str) -> None:
        """Call the supervisor's ``~/NAME`` and wait for the answer."""
        from std_srvs.srv import Trigger

        client = self.clients[name]
        if not client.wait_for_service(timeout_sec=60):
            raise RuntimeError(f"no supervisor answers {name}")
        future = client.call_async(Trigger.Request())
        if not self.spin_until(future.done):
            raise RuntimeError(f"{name}: no answer")

    def rearm(self) -> None:
        """Reset a latched e-stop and arm: the next e-stop has something to stop."""
        if self.estop and self.estop[-1][1]:
            self.call("reset")
            if not self.spin_until(lambda: self.estop[-1][1] is False):
                raise RuntimeError("the e-stop was not cleared")
        self.call("arm")
        if not self.spin_until(lambda: self.state == "armed"):
            raise RuntimeError("the team was not armed")

    def time_estop(self, act) -> float:
        """Seconds from ``act()`` to a latched e-stop arriving here."""
        self.rearm()
        heard = len(self.estop)
        started = time.monotonic()
        act()
        if not self.spin_until(lambda: any(on for _, on in self.estop[heard:])):
            raise RuntimeError("no e-stop arrived")
        return next(t for t, on in self.estop[heard:] if on) - started

    def close(self) -> None:
        """Destroy the node and its context."""
        self.node.destroy_node()
        self.context.try_shutdown()


def run(domain: int, repeats: int) -> dict[str, list[float]]:
    """Every console's e-stop times (seconds), ``repeats`` each."""
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain))
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    port = _free_port()
    py = sys.executable
    procs = [
        subprocess.Popen(
            [py, "-m", "team_supervisor.supervisor_node", "--ros-args", "-p", "robots:=2"],
            env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        ),
        subprocess.Popen(
            [py, "-m", "excavation_bringup.view", "--robots", "2", "--port", str(port)],
            env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        ),
    ]  # fmt: skip
    master, slave = pty.openpty()
    console = subprocess.Popen(
        [py, "-m", "team_supervisor.operator", "--timeout", "60", "console", "--robots", "2"],
        stdin=slave, stdout=slave, stderr=subprocess.DEVNULL, env=env,
    )  # fmt: skip
    os.close(slave)
    procs.append(console)
    watcher = Watcher(domain)
    names = ("ant-operator estop", "ant-operator console", "live view")
    out: dict[str, list[float]] = {name: [] for name in names}
    try:
        screen = b""
        deadline = time.monotonic() + 120
        while b"ant-operator console:" not in screen and time.monotonic() < deadline:
            if select.select([master], [], [], 0.1)[0]:
                screen += os.read(master, 4096)
        for _ in range(repeats):
            out["ant-operator estop"].append(
                watcher.time_estop(
                    lambda: subprocess.run(
                        [py, "-m", "team_supervisor.operator", "--timeout", "60", "estop"],
                        env=env,
                        capture_output=True,
                        check=True,
                    )  # fmt: skip
                )
            )
            out["ant-operator console"].append(watcher.time_estop(lambda: os.write(master, b" ")))
            client = ControlClient(port, pump=lambda: watcher.spin_until(lambda: False, 0.05))
            try:
                client.wait(lambda c=client: "/operator/estop" in c.services, 60)
                out["live view"].append(
                    watcher.time_estop(lambda c=client: c.send("/operator/estop", {}))
                )
            finally:
                client.close()
    finally:
        watcher.close()
        for p in procs:
            p.terminate()
        for p in procs:
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()
        os.close(master)
    return out


def table(times: dict[str, list[float]]) -> str:
    """The Markdown table of :func:`run`'s times."""
    reference = statistics.median(times["ant-operator estop"])
    lines = [
        "| from | e-stops | median, ms | worst, ms | one-shot command / this (median) |",
        "|---|---:|---:|---:|---:|",
    ]
    for name, t in times.items():
        median = statistics.median(t)
        lines.append(
            f"| {name} | {len(t)} | {1000 * median:.1f} | {1000 * max(t):.1f} | "
            f"{reference / median:.0f} x |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``python -m excavation_bringup.estop_bench``."""
    p = argparse.ArgumentParser(prog="estop_bench", description=__doc__.split("\n\n")[0])
    p.add_argument("--domain", type=int, default=88, help="ROS domain (default 88)")
    p.add_argument("--repeats", type=int, default=5, help="e-stops from each console (5)")
    p.add_argument("--write", type=Path, default=None, help="put the table into this file")
    args = p.parse_args(argv)
    if not 0 <= args.domain <= 101 or args.repeats < 1:
        p.error("--domain must be 0-101 and --repeats at least 1")
    times = run(args.domain, args.repeats)
    text = (
        "## E-stop latency (`python -m excavation_bringup.estop_bench`)\n\n"
        "From the operator's action to the latched `/team/estop` arriving at a watcher node "
        "(a supervisor and the live view each in a process of their own, on this machine):\n\n"
        + table(times)
    )
    print(text)
    if args.write is not None:
        replace_marked(args.write, text, MARK)
    return 0


if __name__ == "__main__":
    sys.exit(main())
