"""The documented Ray cluster recipe (docs/evolution.md, "Ray") on two hosts of this machine.

Two network namespaces joined by a veth link (198.18.0.0/15, removed at the end) stand for
two machines; each runs a Ray node with its own temporary directory, both with token
authentication and one token. A driver with another token is refused; a short evolution
spread over both nodes gives the history and best genome of a one-worker run.
"""

from __future__ import annotations

import contextlib
import csv
import os
import secrets
import shutil
import signal
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest

from excavation_bringup.virtual_hosts import VirtualHosts

BIN = Path(sys.executable).parent
HEAD, WORKER = "198.18.8.1", "198.18.8.2"
ARGS = ["--population", "12", "--generations", "2", "--scenarios", "4", "--steps", "60"]
ARGS += ["--robots", "2", "--seed", "7", "--quiet"]


def _run(cmd: list[str], env: dict, timeout: float = 300.0) -> subprocess.CompletedProcess:
    result = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=timeout)
    assert result.returncode == 0, (
        f"{' '.join(cmd)}:\n{result.stdout[-2000:]}{result.stderr[-2000:]}"
    )
    return result


def _kill_namespace(namespace: str) -> None:
    """Every process left in ``namespace`` (this test's Ray nodes, and only them)."""
    pids = subprocess.run(["ip", "netns", "pids", namespace], capture_output=True, text=True)
    for pid in pids.stdout.split():
        try:
            os.kill(int(pid), signal.SIGKILL)
        except ProcessLookupError:
            pass


def _history(run: Path) -> list[dict]:
    with open(run / "history.csv", newline="") as f:
        return [{k: v for k, v in row.items() if k != "seconds"} for row in csv.DictReader(f)]


@contextlib.contextmanager
def _two_node_cluster(name: str) -> Iterator[tuple[VirtualHosts, dict]]:
    """A Ray head on ``HEAD`` and a worker node on ``WORKER``, one token, one CPU each, each in
    a private temporary directory: ``(hosts, env)``; every process in both namespaces is
    killed and the namespaces removed at the end."""
    env = dict(os.environ, RAY_AUTH_MODE="token", RAY_AUTH_TOKEN=secrets.token_hex(32))
    env["RAY_USAGE_STATS_ENABLED"] = "0"
    hosts = VirtualHosts([("head", HEAD), ("worker", WORKER)], name)
    # Ray's session sockets must fit AF_UNIX's 107 bytes: a short directory, not tmp_path
    short = Path(tempfile.mkdtemp(prefix="ray", dir="/tmp"))
    with hosts:
        try:
            common = ["--num-cpus", "1", "--disable-usage-stats"]
            _run(
                [*hosts.prefix("head"), str(BIN / "ray"), "start", "--head", "--port", "6379"]
                + ["--node-ip-address", HEAD, "--include-dashboard=false", *common]
                + ["--temp-dir", str(short / "h")],
                env,
            )
            _run(
                [*hosts.prefix("worker"), str(BIN / "ray"), "start", "--address", f"{HEAD}:6379"]
                + ["--node-ip-address", WORKER, *common, "--temp-dir", str(short / "w")],
                env,
            )
            yield hosts, env
        finally:
            for h in hosts.hosts:
                _kill_namespace(h.namespace)
            shutil.rmtree(short, ignore_errors=True)


@pytest.mark.system
@pytest.mark.serial  # Ray nodes and a compiling driver: alone, after the parallel part
def test_the_documented_recipe_spreads_a_run_over_two_hosts(tmp_path):
    with _two_node_cluster("tray") as (hosts, env):
        nodes = _run(
            [*hosts.prefix("head"), str(BIN / "python"), "-c"]
            + [
                f"import ray; ray.init(address='{HEAD}:6379'); "
                "print(sorted(n['NodeManagerAddress'] for n in ray.nodes() if n['Alive']))"
            ],
            env,
        )
        assert nodes.stdout.strip().splitlines()[-1] == str([HEAD, WORKER])
        wrong = subprocess.run(
            [*hosts.prefix("worker"), str(BIN / "python"), "-c"]
            + [f"import ray; ray.init(address='{HEAD}:6379')"],
            env=env | {"RAY_AUTH_TOKEN": "not-the-token"},
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert wrong.returncode != 0 and "InvalidAuthToken" in wrong.stdout + wrong.stderr
        _run(
            [*hosts.prefix("head"), str(BIN / "ant-evolve"), *ARGS]
            + ["--ray-address", f"{HEAD}:6379", "--out", str(tmp_path / "cluster")],
            env,
            timeout=600,
        )
    _run(
        [str(BIN / "ant-evolve"), *ARGS, "--workers", "1", "--out", str(tmp_path / "one")],
        dict(os.environ),
        timeout=600,
    )
    assert _history(tmp_path / "cluster") == _history(tmp_path / "one")
    assert (tmp_path / "cluster" / "best.json").read_text() == (
        tmp_path / "one" / "best.json"
    ).read_text()


@pytest.mark.system
@pytest.mark.serial
def test_a_campaign_spread_over_two_hosts_survives_a_lost_node(tmp_path):
    """``ant-experiment training --cluster``: runs in chunks on both nodes, each node in a
    private temporary directory; the worker's node is killed once it has run a chunk; the
    campaign finishes on the head with the histories of the same runs trained here."""
    import json
    import time

    campaign = ["training", "--scale", "quick", "--method", "ant", "--setting", "n2"]
    runs = tmp_path / "cluster" / "runs" / "quick"
    with _two_node_cluster("tcam") as (hosts, env):
        driver = subprocess.Popen(
            [*hosts.prefix("head"), str(BIN / "ant-experiment"), *campaign]
            + ["--cluster", f"{HEAD}:6379", "--chunk", "1", "--out", str(tmp_path / "cluster")],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
        )

        def nodes() -> set[str]:
            seen = set()
            for f in runs.glob("*/cluster.json"):
                try:
                    seen |= {c["node_id"] for c in json.loads(f.read_text())["chunks"]}
                except (OSError, ValueError, KeyError):
                    pass
            return seen

        deadline = time.monotonic() + 600
        while len(nodes()) < 2 and driver.poll() is None and time.monotonic() < deadline:
            time.sleep(0.2)
        assert len(nodes()) == 2, driver.communicate()[0][-3000:]  # both nodes ran one
        _kill_namespace(hosts.hosts[1].namespace)  # the worker's node is lost
        out, _ = driver.communicate(timeout=900)
        assert driver.returncode == 0, out[-3000:]
        print("\n".join(line for line in out.splitlines() if "failed" in line))
    here = [str(BIN / "ant-experiment"), *campaign, "--out", str(tmp_path / "here")]
    _run(here, dict(os.environ))
    for k in range(2):
        name = f"ant-n2-r{k}"
        assert _history(runs / name) == _history(tmp_path / "here" / "runs" / "quick" / name)
