"""The suite's Fast DDS profiles: named for every process, parsed by Fast DDS without error."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from excavation_common.middleware import PROFILE_VARIABLES, PROFILES_FILE, use_profiles

# Creates a participant (the moment Fast DDS reads its profiles) and a reliable writer.
MAKE_WRITER = """
import rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import String
rclpy.init()
node = rclpy.create_node("profiles_check")
reliable = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE)
node.create_publisher(String, "/profiles_check", reliable)
node.destroy_node()
rclpy.shutdown()
print("made a writer")
"""


def test_use_profiles_names_the_suites_file_unless_one_is_named():
    env: dict[str, str] = {}
    assert use_profiles(env) == str(PROFILES_FILE)
    assert env == {"FASTRTPS_DEFAULT_PROFILES_FILE": str(PROFILES_FILE)}
    for name in PROFILE_VARIABLES:
        mine = {name: "/etc/my_profiles.xml"}
        assert use_profiles(mine) == "/etc/my_profiles.xml"
        assert mine == {name: "/etc/my_profiles.xml"}


def test_the_profiles_file_is_installed_with_the_package():
    text = PROFILES_FILE.read_text()
    assert "<heartbeatPeriod>" in text and 'is_default_profile="true"' in text


def _make_writer(profiles: Path) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k not in PROFILE_VARIABLES}
    env["FASTRTPS_DEFAULT_PROFILES_FILE"] = str(profiles)
    return subprocess.run(  # Fast DDS logs its parser's errors on stdout
        [sys.executable, "-c", MAKE_WRITER],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        timeout=60,
    )


def test_fast_dds_reads_the_profiles_without_an_error(tmp_path):
    good = _make_writer(PROFILES_FILE)
    assert good.returncode == 0, good.stdout
    assert "made a writer" in good.stdout
    assert "XMLPARSER" not in good.stdout, good.stdout
    # The check can fail: a misspelt element is reported by the same parser.
    bad = tmp_path / "bad.xml"
    bad.write_text(PROFILES_FILE.read_text().replace("heartbeatPeriod", "heartbeatPeriodX"))
    wrong = _make_writer(bad)
    assert "XMLPARSER" in wrong.stdout and "heartbeatPeriodX" in wrong.stdout, wrong.stdout
