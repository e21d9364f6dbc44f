"""``python -m ant_evolution.warmup``: every kind compiles and runs; bad options are refused."""

import json
import subprocess
import sys

import pytest

from ant_evolution import warmup

# Runs ``compile_kind(argv[1])`` in a fresh process and reports, per kernel entry point, the
# decision-program records its compiled signatures take and numba's cache hits and misses.
PROBE = """
import json, sys

import numba

from ant_controller import hand_coded, tissue
from ant_evolution import breakdown, ga_kernel, kernel, warmup
from ant_evolution.baselines import neat_baseline, network
from excavation_sim import world

RECORDS = (hand_coded.HandCodedRules, tissue.TissueRecord, network.NetworkRecord)
ENTRIES = {
    "run_scenarios": kernel.run_scenarios,
    "run_episode": kernel.run_episode,
    "sense_all": world.sense_all,
    "apply_all": world.apply_all,
    "hand_coded_program": hand_coded.hand_coded_program,
    "tissue.decide": tissue.decide,
    "program_decide": network.program_decide,
    "_lay_out": network._lay_out,
    "_mutate_genes": neat_baseline._mutate_genes,
    "record_scenario": breakdown.record_scenario,
    "replay_sense": breakdown.replay_sense,
    "replay_decide": breakdown.replay_decide,
    "replay_apply": breakdown.replay_apply,
    "_mutate": ga_kernel._mutate,
    "_mutate_by_slots": ga_kernel._mutate_by_slots,
}


def programs(sig):
    return [t.instance_class.__name__ for t in sig if getattr(t, "instance_class", None) in RECORDS]


seconds = warmup.compile_kind(sys.argv[1])
report = {
    name: {
        "programs": [programs(sig) for sig in d.signatures],
        "hits": sum(d.stats.cache_hits.values()),
        "misses": sum(d.stats.cache_misses.values()),
    }
    for name, d in ENTRIES.items()
}
print(json.dumps({"seconds": seconds, "cache": numba.config.CACHE_DIR, "entries": report}))
"""

RECORD = {"hand-coded": "HandCodedRules", "ant": "TissueRecord", "network": "NetworkRecord"}
STEP = ("run_scenarios", "run_episode", "sense_all", "apply_all")
PHASES = ("record_scenario", "replay_sense", "replay_decide", "replay_apply")  # ant-bench
# The entry points compile_kind must compile for each kind (its docstring).
ENTRY_POINTS = {
    "hand-coded": (*STEP, "hand_coded_program", *PHASES),
    "ant": (*STEP, "tissue.decide", *PHASES, "_mutate", "_mutate_by_slots"),  # and breeding
    "network": (*STEP, "program_decide", "_lay_out", "_mutate_genes"),
}
# Entry points with a decision program among their arguments.
TAKE_A_PROGRAM = {
    "run_scenarios",
    "run_episode",
    "hand_coded_program",
    "tissue.decide",
    "program_decide",
    "record_scenario",
    "replay_decide",
}


def probe(kind: str) -> dict:
    """``compile_kind(kind)`` in a fresh process: what it compiled (see ``PROBE``)."""
    done = subprocess.run(
        [sys.executable, "-c", PROBE, kind], capture_output=True, text=True, timeout=900
    )
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("kind", warmup.KINDS)
def test_every_kind_compiles_into_the_cache(kind):
    """compile_kind compiles every entry point of its kind, for that kind's program, into
    numba's on-disk cache: a second fresh process loads each of them and compiles none."""
    first = probe(kind)
    for name in ENTRY_POINTS[kind]:
        programs = first["entries"][name]["programs"]
        assert programs, f"{name}: not compiled by compile_kind({kind!r})"
        if name in TAKE_A_PROGRAM:  # only this kind's program ran in the process
            assert all(p == [RECORD[kind]] for p in programs), (name, programs)
    again = probe(kind)
    assert again["cache"] == first["cache"], "kernel sources changed while the test ran"
    for name in ENTRY_POINTS[kind]:
        entry = again["entries"][name]
        assert entry["misses"] == 0 and entry["hits"] >= 1, (name, entry)
        assert entry["programs"] == first["entries"][name]["programs"], name


def test_main_reports_every_kind(capsys):
    assert warmup.main(["--workers", "1"]) == 0
    out = capsys.readouterr().out
    assert "kernels ready in" in out and all(f"{k} " in out for k in warmup.KINDS)


def test_zero_workers_is_refused():
    proc = subprocess.run(
        [sys.executable, "-m", "ant_evolution.warmup", "--workers", "0"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2 and "--workers: must be at least 1, got 0" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_scenario_arrays_have_one_type_however_the_set_arrived():
    """A set made here and one unpickled (as a pool worker gets it) give the kernel the same
    argument types, so the kernel the warm-up compiled is the one every worker loads."""
    import pickle

    import numba

    from ant_evolution.evaluate import ScenarioSet
    from blueprint_server.blueprint import default_blueprint

    batch = ScenarioSet.create(default_blueprint(1), 2, 2, 10, 0)
    here, there = batch.arrays(), pickle.loads(pickle.dumps(batch)).arrays()
    assert numba.typeof(here) == numba.typeof(there)
    assert all(not a.flags.writeable for a in here)
    assert batch.start.heights.flags.writeable  # the set's own arrays are left as they were


def test_the_cache_key_covers_every_file_with_kernels(monkeypatch):
    """The cache folder's hash covers every source file that uses numba in the three kernel
    packages (the episode kernel inlines code from ant_evolution/baselines/network.py), and
    changes when one of them is left out."""
    import importlib.util
    from pathlib import Path

    import ant_controller

    covered: set[Path] = set()
    for name, patterns in ant_controller.KERNEL_SOURCES.items():
        root = Path(importlib.util.find_spec(name).submodule_search_locations[0])
        covered |= {p.resolve() for pattern in patterns for p in root.glob(pattern)}
        for path in root.rglob("*.py"):
            if "numba" in path.read_text(encoding="utf-8"):
                assert path.resolve() in covered, f"{path} uses numba but is not hashed"
    full = ant_controller.source_hash()
    monkeypatch.setitem(ant_controller.KERNEL_SOURCES, "ant_evolution", ("*.py",))
    assert ant_controller.source_hash() != full
