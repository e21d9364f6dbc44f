"""The two launchers of a graph: composed in one process, or a process per node.

:func:`compose` builds every node of a :class:`~excavation_bringup.graph.Graph` on one rclpy
context, as a component container would (this environment has no ``launch``); the caller
adds them to its executor and spins. :class:`ProcessLauncher` starts each node as its own
process of this interpreter (what ``ros2 run`` would start), with its parameters in
``RUN/params/NAME.yaml`` and its output in ``RUN/logs/NAME.log``. It has two modes: a trial
starts every node at once and waits for the final one (:meth:`ProcessLauncher.start`,
:meth:`ProcessLauncher.wait`; the fault harness also kills and restarts single nodes); the
dome runs them under the :class:`~excavation_bringup.supervise.Supervisor`
(:meth:`ProcessLauncher.run`: one at a time in order, restarts with back-off, ordered
shutdown). A trial simply uses no restarts.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import threading
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import yaml

from excavation_bringup.graph import Graph
from excavation_bringup.kinds import kind as node_kind
from excavation_bringup.nodes import NodeSpec
from excavation_bringup.supervise import (
    Kill,
    Report,
    RestartPolicy,
    Start,
    Stop,
    Supervisor,
    control_reports,
)
from excavation_common.files import write_text_atomic
from excavation_common.middleware import use_profiles

# --- composed ---------------------------------------------------------------------------------


def _controller(spec: str, cache: dict):
    """The controller of a genome file or ``"hand-coded"`` (one object per spec)."""
    from ant_controller.controller import Controller

    if spec not in cache:
        hand = spec == "hand-coded"
        cache[spec] = Controller.hand_coded() if hand else Controller.from_file(spec)
    return cache[spec]


def compose(graph: Graph, context, source: str = "") -> dict[str, Any]:
    """Every node of ``graph`` built on ``context``, by name, in start order.

    Parameters are overrides, remaps ``cli_args``; the controllers of one genome share one
    :class:`ant_controller.controller.Controller`; drive executors (lifecycle nodes) are
    configured and activated, as their program does. Nodes that are not ROS nodes of this
    process (the live view) are left out.

    Args:
        graph: What to build.
        context: The rclpy context.
        source: The bag's ``source`` note (the recorder).

    Raises:
        ant_controller.errors.GenomeFormatError: A bad genome file.
    """
    from rclpy.parameter import Parameter

    built: dict[str, Any] = {}
    controllers: dict = {}
    try:
        for spec in graph.nodes:
            if spec.kind == "view":
                continue
            cls = node_kind(spec.kind).load_class()
            kwargs: dict[str, Any] = {
                "context": context,
                "parameter_overrides": [
                    Parameter(k, value=v) for k, v in spec.ros_params().items()
                ],
            }
            if spec.namespace:
                kwargs["namespace"] = spec.namespace
            if spec.remaps:
                kwargs["cli_args"] = ["--ros-args", *(a for r in spec.remaps for a in ("-r", r))]
            if spec.kind == "controller":
                genome = spec.args[1] if spec.args[0] == "--genome" else "hand-coded"
                node = cls(_controller(genome, controllers), **kwargs)
            elif spec.kind == "recorder":
                node = cls(custom_data={"source": source}, **kwargs)
            else:
                node = cls(**kwargs)
            built[spec.name] = node
            if spec.kind == "executor":
                node.trigger_configure()
                node.trigger_activate()
    except BaseException:
        for node in built.values():
            node.destroy_node()
        raise
    return built


def close_composed(executor, nodes, context, recorder=None) -> None:
    """Tear a composed run down: close its bag, destroy its nodes, shut its context."""
    import rclpy

    if recorder is not None:
        recorder.close()
    for node in nodes:
        executor.remove_node(node)
        node.destroy_node()
    executor.shutdown()
    rclpy.try_shutdown(context=context)


class RecorderThread:
    """The bag recorder on its own single-threaded executor, spun by a thread.

    The ``EventsExecutor`` of a continuous trial cannot take the recorder's raw (CDR bytes)
    messages (``SystemError: null argument to internal routine``), so the recorder runs
    beside it, as a second component container would.
    """

    def __init__(self, node, context) -> None:
        from rclpy.executors import SingleThreadedExecutor

        self.node = node
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(node)
        self.running = True
        self.thread = threading.Thread(target=self._spin, name="bag-recorder", daemon=True)
        self.thread.start()

    def _spin(self) -> None:
        while self.running:
            self.executor.spin_once(timeout_sec=0.05)

    def close(self) -> None:
        """Stop spinning, finish the bag and destroy the node."""
        self.running = False
        self.thread.join()
        self.node.close()
        self.executor.remove_node(self.node)
        self.node.destroy_node()
        self.executor.shutdown()


# --- processes --------------------------------------------------------------------------------


def tail(log: Path, lines: int = 20) -> str:
    """The last ``lines`` lines of a log file."""
    if not log.exists():
        return ""
    return "\n".join(log.read_text(errors="replace").splitlines()[-lines:])


class ProcessLauncher:
    """A graph's nodes as processes: start, watch, kill, restart, supervise, stop.

    Args:
        graph: What to run (its run directory holds ``params/``, ``logs/``, results).
        env: Environment of the nodes (default: this one) plus ``ROS_DOMAIN_ID`` of the
            deployment unless ``env`` sets it; discovery stays on this machine unless set.
        policy: The supervisor's restart policy (:meth:`run`).
        echo: :meth:`report` also prints.
        prefixes: Per node name, what its command line starts with (a rehearsal runs a
            robot host's nodes in that host's network namespace: ``ip netns exec NS``).
    """

    def __init__(
        self,
        graph: Graph,
        env: dict[str, str] | None = None,
        policy: RestartPolicy | None = None,
        echo: bool = False,
        prefixes: dict[str, list[str]] | None = None,
    ) -> None:
        self.graph = graph
        self.prefixes = dict(prefixes or {})
        self.run_dir = graph.files.run_dir
        self.specs: dict[str, NodeSpec] = {s.name: s for s in graph.nodes}
        self.env = dict(os.environ if env is None else env)
        self.env.setdefault("ROS_DOMAIN_ID", str(graph.deployment.domain))
        self.env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
        use_profiles(self.env)  # the nodes' middleware settings (excavation_common.middleware)
        self.supervisor = Supervisor.create(graph.nodes, policy or RestartPolicy())
        self.procs: dict[str, subprocess.Popen] = {}
        self.echo = echo
        self.stop_requested = ""
        (self.run_dir / "params").mkdir(parents=True, exist_ok=True)
        (self.run_dir / "logs").mkdir(parents=True, exist_ok=True)
        for spec in graph.nodes:
            self.write_params(spec.name)

    # -- files ---------------------------------------------------------------------------

    def params_file(self, name: str) -> Path:
        """``RUN/params/NAME.yaml``."""
        return self.run_dir / "params" / f"{name}.yaml"

    def write_params(self, name: str) -> None:
        """Write node ``name``'s parameter file from its spec."""
        params = self.specs[name].ros_params()
        doc = {"/**": {"ros__parameters": params}} if params else {}
        write_text_atomic(self.params_file(name), yaml.safe_dump(doc, sort_keys=False))

    def set_params(self, name: str, **values) -> None:
        """Change node ``name``'s parameters before it (re)starts (each value checked).

        Raises:
            excavation_common.params.ParameterError: A value the node would refuse.
        """
        spec = self.specs[name]
        self.specs[name] = replace(spec, params=spec.params.updated(name, **values))
        self.write_params(name)

    def command(self, name: str) -> list[str]:
        """Node ``name``'s command line (after its prefix, if any)."""
        return [*self.prefixes.get(name, []), *self.specs[name].command(self.params_file(name))]

    @property
    def commands(self) -> dict[str, list[str]]:
        """Every node's command line, in start order."""
        return {name: self.command(name) for name in self.specs}

    def log(self, name: str) -> Path:
        """Node ``name``'s log (appended across restarts)."""
        return self.run_dir / "logs" / f"{name}.log"

    # -- a trial's controls ----------------------------------------------------------------

    def start(self, name: str | None = None, command: list[str] | None = None, **popen) -> None:
        """Start node ``name`` (default: every node, in order), with ``command`` if given."""
        if name is None:
            for n in self.specs:
                self.start(n)
            return
        with open(self.log(name), "ab") as out:
            out.write(f"--- {time.strftime('%Y-%m-%d %H:%M:%S')} start\n".encode())
            out.flush()
            popen.setdefault("stdin", subprocess.DEVNULL)
            self.procs[name] = subprocess.Popen(
                command or self.command(name),
                env=self.env,
                stdout=out,
                stderr=subprocess.STDOUT,
                **popen,
            )

    def kill(self, name: str, sig: int = signal.SIGKILL) -> int:
        """Send ``sig`` to node ``name``, wait for it and forget it; returns its exit code."""
        proc = self.procs.pop(name)
        if proc.poll() is None:
            proc.send_signal(sig)
        return proc.wait()

    def check(self) -> None:
        """Raise when a node exited by itself with an error.

        Raises:
            RuntimeError: Naming the node, its exit code and the end of its log.
        """
        for name, proc in self.procs.items():
            if proc.poll() is not None and proc.returncode != 0:
                raise RuntimeError(f"{name} exited with {proc.returncode}:\n{tail(self.log(name))}")

    @property
    def finished(self) -> bool:
        """The final node ended (after its last tick, or by a failure)."""
        final = self.procs.get(self.graph.final)
        return final is not None and final.poll() is not None

    def wait(self, timeout: float, started: float | None = None, idle=None) -> dict:
        """Wait for the final node to end and return its result (``result.json``).

        Args:
            timeout: Seconds from ``started`` (default: now) to give up after.
            started: ``time.monotonic()`` of the run's start.
            idle: Called instead of sleeping 0.1 s between checks (a caller spinning a
                node of its own), or ``None``.

        Raises:
            TimeoutError: Not finished within ``timeout`` seconds of ``started``.
            RuntimeError: A node failed, or the final node wrote no result.
        """
        started = time.monotonic() if started is None else started
        while not self.finished:
            if time.monotonic() - started > timeout:
                raise TimeoutError(f"trial did not finish within {timeout} s")
            self.check()
            if idle is None:
                time.sleep(0.1)
            else:
                idle()
        final = self.graph.final
        code = self.procs[final].returncode
        result = self.graph.files.result
        if code != 0 or not result.exists():
            raise RuntimeError(f"{final} exited with {code}:\n{tail(self.log(final))}")
        return json.loads(result.read_text())

    def stop(self) -> None:
        """Stop every node as Ctrl-C would; the recorder last, so that its bag is complete.

        What outlives 10 s is killed.
        """
        recorder = {n: p for n, p in self.procs.items() if n == "recorder"}
        _interrupt({n: p for n, p in self.procs.items() if n != "recorder"})
        _interrupt(recorder)
        self.procs.clear()

    def __enter__(self) -> ProcessLauncher:
        return self

    def __exit__(self, *exc) -> None:
        self.stop()

    # -- the dome: supervised --------------------------------------------------------------

    def report(self, text: str) -> None:
        """One line into ``RUN/events.log`` (and on stdout with ``echo``)."""
        line = f"{time.strftime('%H:%M:%S')} {text}"
        with open(self.run_dir / "events.log", "a", encoding="utf-8") as events:
            events.write(line + "\n")
        if self.echo:
            print(f"ant-dome: {text}", flush=True)

    def write_state(self) -> None:
        """``RUN/state.json``: each node's pid, state, restarts and last exit code."""
        state = {
            c.name: {
                "pid": self.procs[c.name].pid if c.name in self.procs else None,
                "state": c.state,
                "restarts": c.restarts,
                "exit_code": c.exit_code,
            }
            for c in self.supervisor.children
        }
        write_text_atomic(self.run_dir / "state.json", json.dumps(state, indent=1))

    def _signal(self, name: str, sig: int) -> None:
        proc = self.procs.get(name)
        if proc is not None and proc.poll() is None:
            proc.send_signal(sig)

    def request_stop(self, reason: str) -> None:
        """Ask for the ordered shutdown (from a signal handler: only a flag is set)."""
        self.stop_requested = reason

    def run(self, timeout: float | None = None) -> bool:
        """Start, supervise and finally stop every node; True unless the run failed.

        Args:
            timeout: Stop (as failed) after this many seconds; ``None``: run until the
                final node finishes or a signal arrives.
        """
        import rclpy
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions

        from excavation_common.ros import init_rclpy

        sup = self.supervisor
        context = Context()
        init_rclpy(
            context=context,
            domain_id=int(self.env["ROS_DOMAIN_ID"]),
            signal_handler_options=SignalHandlerOptions.NO,
        )
        node = rclpy.create_node("ant_dome", context=context)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        seen: list[str] = []
        controls: dict[str, str] = {}

        def on_diagnostics(msg) -> None:
            seen.extend(s.name for s in msg.status)
            for report in control_reports(msg.status, controls):
                self.report(report.text)

        node.create_subscription(DiagnosticArray, "/diagnostics", on_diagnostics, 50)
        started = time.monotonic()
        try:
            while not sup.done:
                now = time.monotonic()
                if self.stop_requested:
                    sup.stop(now, self.stop_requested)
                    self.stop_requested = ""
                if timeout is not None and now - started > timeout:
                    sup.stop(now, f"timed out after {timeout:.0f} s", failed=True)
                for name in set(seen):
                    for spec in self.specs.values():
                        if spec.reports(name):
                            sup.ready(spec.name, now)
                seen.clear()
                for name, proc in list(self.procs.items()):
                    code = proc.poll()
                    if code is not None:
                        del self.procs[name]
                        sup.exited(name, code, now)
                changed = False
                for action in sup.poll(now):
                    changed = True
                    match action:
                        case Start(name):
                            # Ctrl-C reaches the dome only: it stops them in order
                            self.start(name, start_new_session=True)
                            self.report(f"starting {name} (pid {self.procs[name].pid})")
                        case Stop(name):
                            self.report(f"stopping {name}")
                            self._signal(name, signal.SIGINT)
                        case Kill(name):
                            self._signal(name, signal.SIGKILL)
                        case Report(text):
                            self.report(text)
                if changed:
                    self.write_state()
                executor.spin_once(timeout_sec=0.05)
        finally:
            for name in list(self.procs):  # only after an exception: nothing may outlive us
                self._signal(name, signal.SIGKILL)
                self.procs[name].wait()
            self.write_state()
            executor.remove_node(node)
            node.destroy_node()
            executor.shutdown()
            rclpy.try_shutdown(context=context)
        return not sup.failure


def _interrupt(procs: dict[str, subprocess.Popen]) -> None:
    """SIGINT every process still running (as Ctrl-C would), then kill what is left."""
    for proc in procs.values():
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
    deadline = time.monotonic() + 10.0
    for proc in procs.values():
        try:
            proc.wait(timeout=max(0.1, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
