"""Robots on their own computers: the site's hosts, each host's share, the network of all."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from excavation_bringup import site as sitefile
from excavation_bringup.dome import dome_graph, main

CONFIG = Path(__file__).resolve().parents[1] / "ros2_ws/src/excavation_bringup/config"
HOSTS = CONFIG / "site_rehearsal_hosts.yaml"


def _variant(tmp_path, old: str, new: str) -> Path:
    """``site_rehearsal_hosts.yaml`` with one text replaced, in ``tmp_path`` (genomes kept)."""
    text = HOSTS.read_text()
    assert old in text
    text = text.replace("../../../../genomes/", str(CONFIG.parents[3] / "genomes") + "/")
    path = tmp_path / "site.yaml"
    path.write_text(text.replace(old, new))
    return path


def test_without_hosts_every_node_runs_on_the_dome_pc(tmp_path):
    site = sitefile.load_site(CONFIG / "site_rehearsal.yaml", emulated=True)
    assert site.hosts == (sitefile.DOME_PC,) and site.robot_host(1) == "dome"
    graph = dome_graph(site, tmp_path, "emulated")
    assert graph.hosts == ["dome"] and graph.share("dome") == graph.nodes


def test_each_robot_host_runs_its_executor_blade_driver_base_and_board(tmp_path):
    site = sitefile.load_site(HOSTS, emulated=True)
    assert [(h.name, h.address) for h in site.hosts] == [
        ("dome", "198.18.0.1"),
        ("robot0", "198.18.0.2"),
        ("robot1", "198.18.0.3"),
    ]
    graph = dome_graph(site, tmp_path, "emulated")
    shares = {host: [n.name for n in graph.share(host)] for host in graph.hosts}
    for k in (0, 1):
        assert shares[f"robot{k}"] == [
            f"base_{k}",
            f"servo_board_{k}",
            f"blade_driver_{k}",
            f"executor_{k}",
        ]
    dome = shares["dome"]
    assert dome[0] == "world" and "supervisor" in dome and dome[-1] == "team_tick"
    assert dome.index("supervisor") < dome.index("controller_0")
    # Every node in exactly one share; the dome's own table (no emulators) places the same.
    assert sorted(sum(shares.values(), [])) == sorted(graph.names)
    dome_table = dome_graph(site, tmp_path / "dome", "dome")
    assert [n.name for n in dome_table.share("robot1")] == ["blade_driver_1", "executor_1"]
    # On its own computer a robot's executor and blade driver wait for a re-arm after a
    # lost heartbeat; on the dome PC they do not (a restarted supervisor resumes the team).
    for spec in graph.nodes:
        if spec.kind in ("executor", "blade_driver"):
            assert spec.params.get("rearm_after_loss", False) is bool(spec.host), spec.name
    one_host = dome_graph(
        sitefile.load_site(CONFIG / "site_rehearsal.yaml", emulated=True),
        tmp_path / "one",
        "emulated",
    )
    assert not any(n.params.get("rearm_after_loss") for n in one_host.nodes)
    with pytest.raises(KeyError, match="no host 'robot7'"):
        graph.share("robot7")
    # --sim has no robot computers: the simulator is every robot.
    sim = dome_graph(sitefile.load_site(CONFIG / "site_sim.yaml", sim=True), tmp_path / "s", "sim")
    assert sim.share("dome") == sim.nodes


def test_every_process_gets_the_sites_network():
    site = sitefile.load_site(HOSTS, emulated=True)
    assert sitefile.environment(site, 9) == {
        "ROS_DOMAIN_ID": "9",
        "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
        "ROS_STATIC_PEERS": "198.18.0.1;198.18.0.2;198.18.0.3",
    }


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        ("host: robot1", "host: robot9", "robots[1].host = 'robot9': not a host of the site"),
        (
            "{name: robot1, address: 198.18.0.3}",
            "{name: robot1, address: 198.18.0.2}",
            "hosts[2].address = '198.18.0.2': hosts[1] has it too",
        ),
        (
            "{name: robot1, address: 198.18.0.3}",
            "{name: robot0, address: 198.18.0.3}",
            "named twice",
        ),
        ("{name: robot1, address: 198.18.0.3}", "{name: Robot 1}", "hosts[2].name = 'Robot 1'"),
        ("address: 198.18.0.3}", "address: 'not an address'}", "hosts[2].address"),
        (
            "{name: robot1, address: 198.18.0.3}",
            "{name: robot1, ip: 1}",
            "hosts[2].ip = 1: unknown key",
        ),
        ("static_peers: [198.18.0.1,", "static_peers: [bad peer,", "network.static_peers[0]"),
        (
            "discovery_range: LOCALHOST",
            "discovery_range: 'OFF'",
            "discovery_range OFF discovers no peer",
        ),
    ],
)
def test_bad_hosts_are_named_by_field_and_value(tmp_path, capsys, old, new, message):
    path = _variant(tmp_path, old, new)
    assert main(["check", str(path), "--rehearse"]) == 1
    assert message in capsys.readouterr().out


def test_ant_dome_plan_prints_each_hosts_share(capsys):
    assert main(["plan", str(HOSTS), "--rehearse", "--json"]) == 0
    plan = json.loads(capsys.readouterr().out)
    assert plan["shares"]["robot0"] == ["base_0", "servo_board_0", "blade_driver_0", "executor_0"]
    assert plan["hosts"]["robot1"] == "198.18.0.3"
    assert plan["network"]["ROS_STATIC_PEERS"] == "198.18.0.1;198.18.0.2;198.18.0.3"
    assert main(["plan", str(HOSTS), "--rehearse"]) == 0
    out = capsys.readouterr().out
    share = "blade_driver_1, executor_1"
    assert f"host robot1 (198.18.0.3, a robot's computer): base_1, servo_board_1, {share}" in out


def test_up_refuses_an_unknown_host_and_recording_off_the_dome_pc(tmp_path, capsys):
    args = ["rehearse", str(HOSTS), "--run-dir", str(tmp_path / "run")]
    assert main([*args, "--host", "robot7"]) == 2
    assert "--host robot7: no host 'robot7' in the site" in capsys.readouterr().err
    assert main([*args, "--host", "robot0", "--record", str(tmp_path / "bag")]) == 2
    assert "--record and --view run on the dome PC (dome)" in capsys.readouterr().err


def test_a_clock_offset_shifts_only_the_wall_clock_of_the_process_it_prefixes():
    """``--clock-offset``'s prefix: ``time.time`` 5 s ahead (or behind) in the child,
    the monotonic clock (timers, timeouts) the same as here."""
    import subprocess
    import sys
    import time

    from excavation_bringup.host_rehearsal import clock_prefix

    probe = "import time; print(time.time(), time.monotonic())"
    for offset in (5.0, -5.0):
        before = time.time()
        out = subprocess.run(
            clock_prefix(offset) + [sys.executable, "-c", probe],
            capture_output=True,
            text=True,
            check=True,
            timeout=60,
        ).stdout.split()
        wall, mono = float(out[0]), float(out[1])
        assert before + offset <= wall <= time.time() + offset
        assert abs(mono - time.monotonic()) < 2.5  # the same clock, not shifted 5 s


@pytest.mark.parametrize(
    "text, message",
    [
        ("robot0", "expected HOST:SECONDS"),
        ("robot0:soon", "not a number"),
        ("robot0:0", "non-zero"),
        ("robot0:7200", "at most 3600"),
    ],
)
def test_a_bad_clock_offset_is_named(text, message):
    from excavation_bringup.host_rehearsal import parse_offset

    with pytest.raises(ValueError, match=message):
        parse_offset(text)
    assert parse_offset("robot1:-0.5") == ("robot1", -0.5, 0.0)


def test_a_clock_offset_on_the_dome_pc_is_refused(tmp_path, capsys):
    code = main(["rehearse", str(HOSTS), "--clock-offset", "dome:1.0", "--run-dir", str(tmp_path)])
    assert code == 2
    assert "--clock-offset dome: not a robot host" in capsys.readouterr().err
