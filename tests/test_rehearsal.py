"""``ant-dome rehearse``: the dome's own node table against emulated drivers, on the wall clock.

A short rehearsal of ``config/site_rehearsal.yaml`` (make test-system): the emulated world,
bases, servo boards, camera and laser, then what ``ant-dome up`` starts in the dome; the team
is armed as an operator would and every tick goes through the real table. The bag it records
holds what the dome's drivers publish, on the site's topics and types, and nothing of the
world behind them.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from helpers.trials import offline_trace

from excavation_bags.reader import open_bag

pytestmark = [pytest.mark.serial, pytest.mark.system]

ROOT = Path(__file__).resolve().parents[1]
SITE = ROOT / "ros2_ws/src/excavation_bringup/config/site_rehearsal.yaml"
GENOME = ROOT / "genomes/best.json"
TICKS = 4


def rehearse(run: Path, domain: int, *extra: str) -> tuple[dict, subprocess.CompletedProcess]:
    """Run ``ant-dome rehearse SITE --ticks TICKS`` in ``run``; its JSON summary and process."""
    command = [sys.executable, "-m", "excavation_bringup.dome", "rehearse", str(SITE)]
    command += ["--ticks", str(TICKS), "--run-dir", str(run), "--domain", str(domain)]
    command += ["--timeout", "900", "--json", *extra]
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    out = subprocess.run(command, capture_output=True, text=True, timeout=1200, env=env)
    lines = out.stdout.strip().splitlines()
    assert out.returncode == 0 and lines, (out.stdout[-2000:], out.stderr[-4000:])
    return json.loads(lines[-1]), out


def startup_warnings(logs: Path) -> list[str]:
    """The WARN and ERROR lines every node logged while the team came up: up to the moment
    the last blade driver saw the team armed (``team armed: blade follows the controller``)."""
    lines = [ln for log in sorted(logs.glob("*.log")) for ln in log.read_text().splitlines()]
    stamp = re.compile(r"^\[(\w+)\] \[(\d+\.\d+)\]")
    armed = [
        float(m.group(2))
        for ln in lines
        if "team armed: blade follows the controller" in ln and (m := stamp.match(ln))
    ]
    assert armed, "no blade driver saw the team armed"
    return [
        ln
        for ln in lines
        if (m := stamp.match(ln))
        and m.group(1) in ("WARN", "ERROR")
        and float(m.group(2)) <= max(armed)
    ]


def test_a_short_rehearsal_takes_every_tick_through_the_dome_table(tmp_path, domain):
    run, bag = tmp_path / "run", tmp_path / "bag"
    summary, _ = rehearse(run, domain, "--record", str(bag))
    assert summary["ok"] and summary["ticks"] == TICKS, summary
    assert "armed the team (as ant-operator arm)" in (run / "events.log").read_text()
    result = json.loads((run / "result.json").read_text())
    assert result["missed"] == {"0": 0, "1": 0}, result
    _, _, trace = offline_trace(str(GENOME), 2, TICKS, 0)
    assert summary["fitness"] >= 0.9 * trace[TICKS]
    assert startup_warnings(run / "logs") == []  # a new user reads them as faults

    # the real table: the blade drivers on the serial backend, ports on the emulated boards
    params = (run / "params" / "blade_driver_0.yaml").read_text()
    assert "backend: serial" in params and str(run / "robot_0_blade") in params
    recorded = open_bag(bag).topics
    count = {name: info.count for name, info in recorded.items()}
    # robot_0's base takes TwistStamped on its diff_drive_controller topic, robot_1's Twist
    assert recorded["/robot_0/diff_drive_controller/cmd_vel"].msgtype.endswith("TwistStamped")
    assert recorded["/robot_1/cmd_vel_unstamped"].msgtype == "geometry_msgs/msg/Twist"
    assert count["/robot_0/diff_drive_controller/cmd_vel"] > 0
    assert count["/robot_1/cmd_vel_unstamped"] > 0
    # poses from the localiser on JPEG frames, heights from the mapper on the laser's scans
    for topic in (
        "/overhead/image_raw/compressed",
        "/overhead/camera_info",
        "/worksite/scan",
        "/worksite/laser_mount/joint_states",
        "/robot_0/pose",
        "/robot_1/pose",
        "/worksite/height_map",
        "/robot_0/blade/joint_states",
        "/robot_0/imu",
    ):
        assert count.get(topic, 0) > 0, topic
    assert "/robot_1/imu" not in count  # robot_1 carries no IMU: R1 from the height map
    # the world behind the drivers stays out of the dome's graph
    assert not [t for t in count if t.startswith(("/sim/", "/truth/"))]
