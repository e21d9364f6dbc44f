"""A campaign's runs as Ray tasks: ``ant-experiment NAME --cluster ADDRESS``.

``--ray-address`` spreads each generation's evaluations over Ray; ``--cluster`` spreads
whole runs instead, one run per task, its evaluations local to the node that runs it.
A task runs a **chunk** of a run (:data:`CHUNK` generations): it gets the run's files (its
configuration, history, checkpoint, best genome) from the driver, restores them into a
private temporary directory on its node, resumes the run there for the chunk and returns
the files. The driver writes them into the campaign directory (each file atomically, the
checkpoint last) and submits the run's next chunk, so nothing leans on a disk shared
between nodes, and a run survives the loss of any node: a chunk whose node died is
submitted again from the run's last files on the driver's disk, and a driver that is
killed resumes every run from there when started again. Runs resume bit for bit
(:func:`ant_evolution.evolve.run_evolution`), so a campaign on a cluster gives the same
histories as the same runs trained here.

Each run directory gets ``cluster.json``: the node (Ray node id and address) that ran each
chunk; ``ant-experiment status`` shows where the runs in progress ran last.
"""

from __future__ import annotations

import csv
import json
import os
import socket
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

from excavation_common.files import write_text_atomic

CHUNK = 50
"""Generations per task (a lost node costs at most this many of one run)."""
RUN_FILES = (
    "config.yaml",
    "history.csv",
    "best.json",
    "fitness.png",
    "neat-checkpoint.gz",
    "checkpoint.json",
)
"""A run's files a chunk carries, the checkpoint last (written last: a driver killed while
writing a chunk's files resumes from the previous checkpoint)."""
FAIL_ONCE = "ANT_CLUSTER_FAIL_ONCE"
"""Tests: ``NAME=MARKER``: the first chunk of run directory NAME fails on its node (as if
the node were lost) unless the file MARKER exists, which the failure creates."""


def run_chunk(method: str, config: dict, files: dict[str, bytes], generations: int) -> dict:
    """On a node: resume one run for ``generations`` generations; its files and the node.

    Runs in a private temporary directory (nothing is read from or left on a shared
    disk), on one core.
    """
    from ant_evolution.baseline_runs import run_fixed, run_neat
    from ant_evolution.evolve import config_from_dict, run_evolution

    name = files.pop("__name__").decode()
    failing, _, marker = os.environ.get(FAIL_ONCE, "").partition("=")
    if failing == name and marker and not Path(marker).exists():
        Path(marker).write_text("failed once\n")
        raise RuntimeError(f"{name}: this node was lost (the test's fault)")
    with tempfile.TemporaryDirectory(prefix="ant-run-") as tmp:
        d = Path(tmp)
        for file, data in files.items():
            (d / file).write_bytes(data)
        resume = (d / "checkpoint.json").exists() or (d / "neat-checkpoint.gz").exists()
        run = {"ant": run_evolution, "ant-nocc": run_evolution, "fixed": run_fixed}.get(
            method, run_neat
        )
        run(config_from_dict(config), d, workers=1, resume=resume, stop_after=generations)
        out = {f: (d / f).read_bytes() for f in RUN_FILES if (d / f).exists()}
    return {"files": out, "node": _node()}


def _node() -> dict:
    """This task's node: its Ray node id and its host's name."""
    import ray

    return {"node_id": ray.get_runtime_context().get_node_id(), "host": socket.gethostname()}


def _files_of(d: Path, name: str) -> dict[str, bytes]:
    out = {f: (d / f).read_bytes() for f in RUN_FILES if (d / f).exists()}
    out["__name__"] = name.encode()
    return out


def _write_run(d: Path, files: dict[str, bytes]) -> None:
    """A chunk's files into the run directory, each atomically, the checkpoint last."""
    d.mkdir(parents=True, exist_ok=True)
    for f in RUN_FILES:
        if f in files:
            tmp = d / f".{f}.tmp"
            tmp.write_bytes(files[f])
            os.replace(tmp, d / f)


def _record(d: Path, node: dict, generation: int) -> None:
    path = d / "cluster.json"
    chunks = json.loads(path.read_text())["chunks"] if path.exists() else []
    chunks.append({"generations": generation, **node, "wall": time.time()})
    write_text_atomic(path, json.dumps({"chunks": chunks}, indent=1) + "\n")


def history_length(path: Path) -> int:
    """Generations a ``history.csv`` holds (0: none yet)."""
    if not path.exists():
        return 0
    with open(path, newline="") as f:
        return sum(1 for _ in csv.DictReader(f))


def train_on_cluster(
    runs: Sequence[tuple[Path, str, object]], address: str, progress=None
) -> dict[str, int]:
    """Train every run of ``runs`` on the Ray cluster at ``address`` (``local``: here).

    ``runs``: ``(directory, method, EvolveConfig)``. Returns the chunks each node ran (by
    host).

    A chunk that fails (its node lost, its worker killed) is submitted again from the
    run's files here, up to 3 times a run.

    Raises:
        RuntimeError: A run failed more than 3 times.
    """
    import ray

    if not ray.is_initialized():
        if address == "local":
            ray.init(include_dashboard=False, log_to_driver=False)
        else:
            ray.init(address=address, log_to_driver=False)
    remote = ray.remote(num_cpus=1, max_retries=0)(run_chunk)
    failures: dict[tuple, int] = {}
    per_node: dict[str, int] = {}
    pending = {}

    def submit(job) -> bool:
        d, method, config = job
        done = history_length(d / "history.csv")
        if done >= config.generations:
            return False
        chunk = min(CHUNK, config.generations - done)
        ref = remote.remote(method, config.to_dict(), _files_of(d, d.name), chunk)
        pending[ref] = job
        return True

    for job in runs:
        submit(job)
    while pending:
        ready, _ = ray.wait(list(pending), num_returns=1)
        ref = ready[0]
        job = pending.pop(ref)
        d = job[0]
        try:
            result = ray.get(ref)
        except ray.exceptions.RayError as exc:
            failures[job] = failures.get(job, 0) + 1
            if failures[job] > 3:
                raise RuntimeError(f"{d.name}: failed {failures[job]} times: {exc}") from None
            if progress is not None:
                progress(f"{d.name}: a chunk failed ({type(exc).__name__}); again from its files")
            submit(job)
            continue
        _write_run(d, result["files"])
        generation = history_length(d / "history.csv")
        _record(d, result["node"], generation)
        host = result["node"]["host"]
        per_node[host] = per_node.get(host, 0) + 1
        if progress is not None:
            progress(f"{d.name}: generation {generation} (on {host})")
        submit(job)
    return per_node
