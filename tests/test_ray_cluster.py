"""The documented Ray cluster recipe (docs/evolution.md, "Ray") on two hosts of this machine.

Two network namespaces joined by a veth link (198.18.0.0/15, removed at the end) stand for
two machines; each runs a Ray node with its own temporary directory, both with token
authentication and one token. A driver with another token is refused; a short evolution
spread over both nodes gives the history and best genome of a one-worker run.
"""

from __future__ import annotations

import csv
import os
import secrets
import shutil
import signal
import subprocess
import sys
import tempfile
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


@pytest.mark.system
@pytest.mark.serial  # Ray nodes and a compiling driver: alone, after the parallel part
def test_the_documented_recipe_spreads_a_run_over_two_hosts(tmp_path):
    env = dict(os.environ, RAY_AUTH_MODE="token", RAY_AUTH_TOKEN=secrets.token_hex(32))
    env["RAY_USAGE_STATS_ENABLED"] = "0"
    hosts = VirtualHosts([("head", HEAD), ("worker", WORKER)], "tray")
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
        finally:
            for h in hosts.hosts:
                _kill_namespace(h.namespace)
            shutil.rmtree(short, ignore_errors=True)
    _run(
        [str(BIN / "ant-evolve"), *ARGS, "--workers", "1", "--out", str(tmp_path / "one")],
        dict(os.environ),
        timeout=600,
    )
    assert _history(tmp_path / "cluster") == _history(tmp_path / "one")
    assert (tmp_path / "cluster" / "best.json").read_text() == (
        tmp_path / "one" / "best.json"
    ).read_text()
