"""Every ROS package declares what it imports (package.xml and setup.py install_requires)."""

from __future__ import annotations

import ast
import re
import sys
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "ros2_ws" / "src"
# The Python packages (ament_python); the message packages (ament_cmake) import nothing.
PACKAGES = sorted(p.name for p in SRC.iterdir() if (p / "setup.py").is_file())

# Python import name -> (rosdep key for package.xml, pip name for install_requires).
THIRD_PARTY = {
    "numpy": ("python3-numpy", "numpy"),
    "numba": ("python3-numba", "numba"),
    "cv2": ("python3-opencv", "opencv-python-headless"),
    "yaml": ("python3-yaml", "pyyaml"),
    "serial": ("python3-serial", "pyserial"),
    "matplotlib": ("python3-matplotlib", "matplotlib"),
    "PIL": ("python3-pil", "pillow"),
    "tqdm": ("python3-tqdm", "tqdm"),
    "rosbags": ("python3-rosbags", "rosbags"),
    "mcap": ("python3-mcap", "mcap"),
    "mcap_ros2": ("python3-mcap-ros2", "mcap-ros2-support"),
    "foxglove": ("python3-foxglove-sdk", "foxglove-sdk"),
    "websockets": ("python3-websockets", "websockets"),
    "libfaketime": ("python3-libfaketime-pip", "libfaketime"),
}
ROS_PACKAGES = re.compile(r"^(rclpy|std_srvs|ament_index_python|\w+_msgs|\w+_interfaces)$")


def imports_of(package: str) -> set[str]:
    """Top-level names imported anywhere in a package's modules (tests excluded)."""
    names = set()
    for path in (SRC / package / package).rglob("*.py"):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names.update(a.name.split(".")[0] for a in node.names)
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names.add(node.module.split(".")[0])
    return names - {package} - set(sys.stdlib_module_names) - {"__future__"}


def exec_depends(package: str) -> set[str]:
    xml = (SRC / package / "package.xml").read_text(encoding="utf-8")
    return set(re.findall(r"<(?:exec_)?depend>([^<]+)</(?:exec_)?depend>", xml))


def install_requires(package: str) -> set[str]:
    tree = ast.parse((SRC / package / "setup.py").read_text(encoding="utf-8"))
    for node in ast.walk(tree):
        if isinstance(node, ast.keyword) and node.arg == "install_requires":
            return {ast.literal_eval(e) for e in node.value.elts}
    return set()


@pytest.mark.parametrize("package", PACKAGES)
def test_package_xml_and_install_requires_list_every_import(package):
    missing_xml, missing_pip, unknown = [], [], []
    deps, requires = exec_depends(package), install_requires(package)
    for name in sorted(imports_of(package)):
        if name == "ant_evolution":  # our offline package: a pip project, not a ROS package
            if "ant-evolution" not in requires:
                missing_pip.append("ant-evolution")
        elif name in PACKAGES:
            if name not in deps:
                missing_xml.append(name)
            if name not in requires:
                missing_pip.append(name)
        elif ROS_PACKAGES.match(name):
            if name not in deps:
                missing_xml.append(name)
        elif name in THIRD_PARTY:
            key, pip_name = THIRD_PARTY[name]
            if key not in deps:
                missing_xml.append(key)
            if pip_name not in requires:
                missing_pip.append(pip_name)
        else:
            unknown.append(name)
    assert not unknown, f"{package} imports {unknown}: add them to THIRD_PARTY here"
    assert not missing_xml, f"{package}/package.xml lacks exec_depend {missing_xml}"
    assert not missing_pip, f"{package}/setup.py install_requires lacks {missing_pip}"


@pytest.mark.parametrize("package", PACKAGES)
def test_no_stale_dependency_on_our_packages(package):
    """A package.xml naming a package of ours that the code never imports misleads colcon.

    The bring-up also depends on what it launches: the packages of the node kinds its graph
    starts by module name (its registry, ``excavation_bringup.kinds``).
    """
    used = imports_of(package)
    if package == "excavation_bringup":
        from excavation_bringup.kinds import KINDS

        used |= {k.package for k in KINDS.values()}
    stale = sorted(d for d in exec_depends(package) if d in PACKAGES and d not in used)
    assert not stale, f"{package}/package.xml depends on {stale} but never imports them"


def test_the_bring_up_depends_on_every_package_it_launches():
    """``ros2 run`` in an installed workspace needs each launched package installed too."""
    from excavation_bringup.kinds import KINDS

    launched = {k.package for k in KINDS.values()} & set(PACKAGES)
    missing = sorted(launched - exec_depends("excavation_bringup"))
    assert not missing, f"excavation_bringup/package.xml lacks exec_depend {missing}"


@pytest.mark.parametrize("package", PACKAGES)
def test_no_dependency_is_listed_twice(package):
    xml = (SRC / package / "package.xml").read_text(encoding="utf-8")
    listed = re.findall(r"<(?:exec_|test_|build_)?depend>([^<]+)</", xml)
    twice = sorted({d for d in listed if listed.count(d) > 1})
    assert not twice, f"{package}/package.xml lists {twice} twice"


def test_no_package_imports_another_packages_private_names():
    """``from other_pkg.mod import _name`` couples two packages through an internal detail."""
    ours = set(PACKAGES) | {"ant_evolution"}
    roots = [SRC / p / p for p in PACKAGES] + [SRC.parents[1] / "evolution" / "ant_evolution"]
    offenders = []
    for root in roots:
        for path in root.rglob("*.py"):
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                if not isinstance(node, ast.ImportFrom) or not node.module or node.level:
                    continue
                top = node.module.split(".")[0]
                if top in ours and top != root.name:
                    offenders += [
                        f"{path.name}: {node.module}.{a.name}"
                        for a in node.names
                        if a.name.startswith("_")
                    ]
    assert not offenders, offenders
