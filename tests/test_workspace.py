"""The ROS 2 workspace builds with colcon into what ``ros2 run`` looks up."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

# One worker takes the whole module (--dist loadgroup), so the module's colcon build runs
# once: split over two workers, each built the workspace (23 s each on 2 cores).
pytestmark = pytest.mark.xdist_group("colcon")

ROOT = Path(__file__).resolve().parents[1]
INTERFACE_PACKAGES = ["tf2_msgs"]
PACKAGES = {
    "excavation_common": [],
    "ant_controller": ["genome_info", "controller"],
    "blueprint_server": ["blueprint_info", "server"],
    "excavation_sim": ["sim", "sensors", "dynamics"],
    "overhead_localizer": ["localizer", "calibrate"],
    "terrain_mapper": ["mapper", "field-metrics", "calibrate_mount"],
    "blade_driver": ["driver", "fake_board"],
    "team_supervisor": ["supervisor", "ant-operator"],
    "excavation_bags": ["ant-bag"],
    "drive_executor": ["executor"],
    "team_tick": ["team_tick"],
    "excavation_bringup": ["ant-trial", "ant-dome", "ant-view"],
    "excavation_field": ["ant-soak", "ant-field-experiment"],
    "dome_emulator": ["base", "servo_board", "camera", "laser"],
}


@pytest.fixture(scope="module")
def install(tmp_path_factory):
    base = tmp_path_factory.mktemp("colcon")
    venv = Path(sys.executable).parent.parent
    env = dict(
        os.environ,
        PATH=f"{Path(sys.executable).parent}:{os.environ['PATH']}",
        AMENT_PREFIX_PATH=str(venv),
    )
    result = subprocess.run(
        [
            str(Path(sys.executable).parent / "colcon"),
            "--log-base",
            str(base / "log"),
            "build",
            "--base-paths",
            str(ROOT / "ros2_ws" / "src"),
            "--build-base",
            str(base / "build"),
            "--install-base",
            str(base / "install"),
            # The interface packages (ament_cmake) are built into the venv by make setup
            # (tools/build_interfaces.py, tests/test_interfaces.py); this is the Python side,
            # which finds them there as installed dependencies.
            "--packages-ignore",
            *INTERFACE_PACKAGES,
        ],
        cwd=base,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    return base / "install"


@pytest.mark.parametrize("package", sorted(PACKAGES))
def test_ament_python_layout(install, package):
    prefix = install / package
    marker = prefix / "share" / "ament_index" / "resource_index" / "packages" / package
    assert marker.is_file()
    assert (prefix / "share" / package / "package.xml").is_file()
    # colcon only writes the ament hooks when catkin_pkg accepted the package.xml
    assert (prefix / "share" / package / "package.dsv").is_file()
    for exe in PACKAGES[package]:
        path = prefix / "lib" / package / exe
        assert path.is_file() and os.access(path, os.X_OK)


def test_ros2_run_lookup_runs_the_executable(install, tmp_path):
    """Resolve lib/<pkg>/<exe> through AMENT_PREFIX_PATH as ``ros2 run`` does, then run it."""
    script = (
        f"source {install}/setup.bash && "
        f"{sys.executable} -c 'from ament_index_python.packages import get_package_prefix;"
        f' print(get_package_prefix("blueprint_server"))\''
    )
    out = subprocess.run(
        ["bash", "-c", script], capture_output=True, text=True, timeout=60, check=True
    )
    prefix = Path(out.stdout.strip().splitlines()[-1])
    assert prefix == install / "blueprint_server"
    run = subprocess.run(
        [str(prefix / "lib" / "blueprint_server" / "blueprint_info"), "default:3"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert run.returncode == 0, run.stderr
    assert "goal depths [3]" in run.stdout


def test_nothing_in_the_repository_points_outside_it():
    """Code and docs speak of the project's own files: no design notes kept elsewhere."""
    files = subprocess.run(
        ["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True
    ).stdout.split()
    outside = ("DESIGN.md", "STYLE.md", "../shared")
    found = []
    for name in files:
        path = ROOT / name
        if path.suffix not in {".py", ".md", ".toml", ".cfg", ".yaml", ".xml", ".txt", ""}:
            continue
        if not path.is_file() or name == "tests/test_workspace.py":
            continue
        text = path.read_text(errors="replace")
        found += [f"{name}: {word}" for word in outside if word in text]
    assert found == []
