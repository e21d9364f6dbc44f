"""Robots on their own hosts, rehearsed on one machine: a network namespace per host.

A short rehearsal of ``config/site_rehearsal_hosts.yaml`` (make test-system): the dome PC and
each robot host in a namespace of their own, joined by veth links on 198.18.0.0/15, every
process discovering the others across the links by unicast to the site's static peers. A
drill takes robot0's link down for 2 s and re-arms the team 3 s after it returns; the
robot's own nodes must hold it still until then. Another runs robot0's processes on a clock a
second ahead of the dome PC's.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from helpers.view_client import Client, free_port

pytestmark = [pytest.mark.serial, pytest.mark.system]

ROOT = Path(__file__).resolve().parents[1]
SITE = ROOT / "ros2_ws/src/excavation_bringup/config/site_rehearsal_hosts.yaml"
TICKS = 2
VIEW = ("/view/robots", "/view/height_map", "/view/blueprint", "/view/fitness", "/tf")


def _namespaces() -> set[str]:
    out = subprocess.run(["ip", "netns", "list"], capture_output=True, text=True).stdout
    return {line.split()[0] for line in out.splitlines() if re.match(r"ant\d+-\d", line)}


def _rehearse(tmp_path, domain, *drill: str) -> Path:
    """A ``TICKS``-tick rehearsal of the hosts' site with ``drill``; its run directory."""
    run = tmp_path / "run"
    command = [sys.executable, "-m", "excavation_bringup.dome", "rehearse", str(SITE)]
    command += ["--ticks", str(TICKS), "--run-dir", str(run), "--domain", str(domain)]
    command += ["--timeout", "900", "--json", *drill]
    out = subprocess.run(command, capture_output=True, text=True, timeout=1200, env=os.environ)
    lines = out.stdout.strip().splitlines()
    assert out.returncode == 0 and lines, (out.stdout[-2000:], out.stderr[-4000:])
    summary = json.loads(lines[-1])
    assert summary["ok"] and summary["ticks"] == TICKS, summary
    return run


def test_hosts_in_their_namespaces_take_every_tick_and_a_dropped_link_waits_for_a_re_arm(
    tmp_path, domain
):
    before = _namespaces()
    run = _rehearse(tmp_path, domain, "--drop-link", "robot0:30:2")
    result = json.loads((run / "result.json").read_text())
    assert result["missed"] == {"0": 0, "1": 0}, result
    events = (run / "events.log").read_text()
    assert "armed the team" in events and "starting executor_0" in events
    # The robot host's own recorder heard its executor (same host) and the heartbeat (across).
    drill = json.loads((run / "drill.json").read_text())
    assert drill["link_down"] < drill["link_up"] < drill["rearm"], drill
    robot = drill["robot_0"]
    assert robot["drive_zero_after_fault_s"] is not None, drill  # the executor stopped it
    assert robot["blade_home_after_fault_s"] is not None, drill  # the driver homed the blade
    assert robot["non_zero_commands_between_link_up_and_rearm"] == 0, drill
    # The namespaces went with the run.
    assert _namespaces() <= before


def test_a_robot_host_whose_clock_runs_a_second_ahead_stands_still_and_says_why(tmp_path, domain):
    """``--clock-offset robot0:1.0``: robot0's processes (libfaketime) see every pose 1 s
    old, past the executor's ``pose_timeout``: the robot never moves, its executor names
    the clock on /diagnostics, and the team's ticks complete without it."""
    # The live view runs on the dome PC, in its namespace: its port is forwarded to this
    # machine's loopback, where a Foxglove client reads the view's channels.
    port = free_port()
    client = Client(port, list(VIEW), connect_within=600)
    client.start()
    try:
        run = _rehearse(
            tmp_path, domain, "--clock-offset", "robot0:1.0", "--view", "--view-port", str(port)
        )
    finally:
        client.stop.set()
        client.join(10)
    assert client.error is None and set(VIEW) <= set(client.last), (client.error, client.last)
    assert json.loads((run / "result.json").read_text())["missed"] == {"0": 0, "1": 0}
    drill = json.loads((run / "drill.json").read_text())
    robot = drill["robot_0"]
    assert robot["drive_commands"] > 0 and robot["drive_commands_not_zero"] == 0, drill
    assert robot["wheel_commands_not_zero"] == 0, drill
    said = " ".join(robot["diagnostics"].get("/robot_0/executor", []))
    assert "clock runs ahead of the pose's" in said, drill
