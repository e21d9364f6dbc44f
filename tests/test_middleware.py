"""The suite's Fast DDS profiles: named for every process, parsed by Fast DDS without error,
no shared-memory transport on loopback."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from excavation_common.middleware import (
    LOOPBACK_PROFILES_FILE,
    PROFILE_VARIABLES,
    PROFILES_FILE,
    RANGE_VARIABLE,
    use_profiles,
)

# Creates a participant (the moment Fast DDS reads its profiles) and a reliable writer, waits
# until a reader of its own matches it, then prints the shared-memory files it has mapped.
MAKE_WRITER = """
import time
import rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import String
rclpy.init()
node = rclpy.create_node("profiles_check")
reliable = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE)
pub = node.create_publisher(String, "/profiles_check", reliable)
node.create_subscription(String, "/profiles_check", lambda m: None, reliable)
deadline = time.monotonic() + 30
while pub.get_subscription_count() == 0 and time.monotonic() < deadline:
    rclpy.spin_once(node, timeout_sec=0.05)
with open("/proc/self/maps") as f:
    shm = sorted({line.split()[-1] for line in f if "/dev/shm/fastrtps" in line})
print("made a writer", pub.get_subscription_count(), "shm:", " ".join(shm) or "none")
node.destroy_node()
rclpy.shutdown()
"""


def test_use_profiles_names_the_suites_file_unless_one_is_named():
    env: dict[str, str] = {}
    assert use_profiles(env) == str(PROFILES_FILE)
    assert env == {"FASTRTPS_DEFAULT_PROFILES_FILE": str(PROFILES_FILE)}
    for name in PROFILE_VARIABLES:
        mine = {name: "/etc/my_profiles.xml", RANGE_VARIABLE: "LOCALHOST"}
        assert use_profiles(mine) == "/etc/my_profiles.xml"
        assert mine == {name: "/etc/my_profiles.xml", RANGE_VARIABLE: "LOCALHOST"}


def test_localhost_gets_the_loopback_profile_once_and_for_every_child():
    env = {RANGE_VARIABLE: "LOCALHOST"}
    assert use_profiles(env) == str(LOOPBACK_PROFILES_FILE)
    assert env == {
        RANGE_VARIABLE: "SYSTEM_DEFAULT",
        "FASTRTPS_DEFAULT_PROFILES_FILE": str(LOOPBACK_PROFILES_FILE),
    }
    again = dict(env)
    assert use_profiles(again) == str(LOOPBACK_PROFILES_FILE) and again == env
    # A child's environment copied from this one that names LOCALHOST again (tests do).
    child = dict(env, **{RANGE_VARIABLE: "LOCALHOST"})
    assert use_profiles(child) == str(LOOPBACK_PROFILES_FILE) and child == env
    # ... or another range: the plain profile, that range.
    subnet = dict(env, **{RANGE_VARIABLE: "SUBNET"})
    assert use_profiles(subnet) == str(PROFILES_FILE) and subnet[RANGE_VARIABLE] == "SUBNET"
    # Static peers need rmw's own LOCALHOST handling (SYSTEM_DEFAULT ignores them).
    peers = {RANGE_VARIABLE: "LOCALHOST", "ROS_STATIC_PEERS": "198.18.0.2"}
    assert use_profiles(peers) == str(PROFILES_FILE) and peers[RANGE_VARIABLE] == "LOCALHOST"


def test_the_profiles_files_are_installed_with_the_package():
    for path in (PROFILES_FILE, LOOPBACK_PROFILES_FILE):
        text = path.read_text()
        assert "<heartbeatPeriod>" in text and 'is_default_profile="true"' in text
    loopback = LOOPBACK_PROFILES_FILE.read_text()
    assert "<useBuiltinTransports>false</useBuiltinTransports>" in loopback
    assert "<address>127.0.0.1</address>" in loopback and "SHM" not in loopback


def _make_writer(env_changes: dict[str, str], domain: int) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k not in (*PROFILE_VARIABLES, RANGE_VARIABLE)}
    env.update(env_changes, ROS_DOMAIN_ID=str(domain))
    return subprocess.run(  # Fast DDS logs its parser's errors on stdout
        [sys.executable, "-c", MAKE_WRITER],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        timeout=60,
    )


@pytest.mark.parametrize("profiles", [PROFILES_FILE, LOOPBACK_PROFILES_FILE], ids=lambda p: p.name)
def test_fast_dds_reads_the_profiles_without_an_error(tmp_path, domains, profiles):
    good = _make_writer({"FASTRTPS_DEFAULT_PROFILES_FILE": str(profiles)}, domains())
    assert good.returncode == 0, good.stdout
    assert "made a writer 1" in good.stdout, good.stdout
    assert "XMLPARSER" not in good.stdout, good.stdout
    # The check can fail: a misspelt element is reported by the same parser.
    bad = tmp_path / "bad.xml"
    bad.write_text(profiles.read_text().replace("heartbeatPeriod", "heartbeatPeriodX"))
    wrong = _make_writer({"FASTRTPS_DEFAULT_PROFILES_FILE": str(bad)}, domains())
    assert "XMLPARSER" in wrong.stdout and "heartbeatPeriodX" in wrong.stdout, wrong.stdout


def test_no_participant_of_the_suite_maps_shared_memory_on_loopback(domains):
    env: dict[str, str] = {RANGE_VARIABLE: "LOCALHOST"}
    use_profiles(env)
    ours = _make_writer(env, domains())
    assert "made a writer 1 shm: none" in ours.stdout, ours.stdout
    # The check can fail: rmw_fastrtps's own LOCALHOST setting maps Fast DDS's segments.
    rmw = _make_writer(
        {RANGE_VARIABLE: "LOCALHOST", "FASTRTPS_DEFAULT_PROFILES_FILE": str(PROFILES_FILE)},
        domains(),
    )
    assert "made a writer 1 shm: /dev/shm/fastrtps" in rmw.stdout, rmw.stdout
