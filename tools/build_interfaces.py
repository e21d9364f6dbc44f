"""Build the workspace's ROS interface packages into the venv (``make setup`` runs this).

The ROS 2 Jazzy wheels carry rclpy, the common interfaces and the message generators
(``ament_cmake``, ``rosidl_default_generators``), but no package of ours: an
``ament_cmake`` package of ``.msg``/``.action`` files under ``ros2_ws/src`` (today
``tf2_msgs``) is generated and compiled here with colcon, cmake and the C compiler, and
installed into the venv's own prefix. There the generated Python modules are on the
interpreter's path and the typesupport libraries sit in ``VENV/lib`` beside the wheels'
own, which the wheels' bootstrap (``ros-wheels-bootstrapper``) puts on the library path of
every venv python: nothing needs sourcing.

One fix-up makes the build possible. The wheels were built in a manylinux container, and
each ``share/PKG/cmake/*Export.cmake`` of a message package names that container's include
directories (``/opt/python/cp311-cp311/include/python3.11`` and numpy's under it); CMake
refuses an imported target whose include directory is missing. :func:`fix_exports`
rewrites those directories to this interpreter's and numpy's own (recomputed each time, so
running it twice changes nothing). A reinstalled wheel brings the old line back: ``make
setup`` runs this after every install.

Before a build, what the previous build installed (its ``install_manifest.txt`` files) and
its build folder are removed, so a renamed or removed message does not linger in the venv.

Usage: ``python tools/build_interfaces.py`` (with the venv's python; ``--check`` only
checks for cmake and a C compiler).
"""

from __future__ import annotations

import argparse
import glob
import os
import re
import shutil
import subprocess
import sys
import sysconfig
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "ros2_ws" / "src"
BUILD = Path(sys.prefix) / "interfaces-build"
"""The colcon build folder, kept with the venv (the next build removes its installs)."""

_PYTHON_OR_NUMPY = re.compile(
    r"^(.*/include/python\d+\.\d+|.*/site-packages/numpy/(_core|core)/include)$"
)
_INCLUDES = re.compile(r'^(\s*INTERFACE_INCLUDE_DIRECTORIES\s+")([^"]*)(")', re.M)


class BuildError(RuntimeError):
    """Something the build needs is missing (the message says what and how to get it)."""


def interface_packages(src: Path = SRC) -> list[str]:
    """The ``ament_cmake`` packages under ``src`` (by their ``package.xml``), sorted."""
    out = []
    for xml in sorted(src.glob("*/package.xml")):
        text = xml.read_text()
        if "<build_type>ament_cmake</build_type>" in text:
            out.append(re.search(r"<name>\s*([\w-]+)\s*</name>", text).group(1))
    return out


def rewrite_includes(text: str, python_include: str, numpy_include: str) -> str:
    """``text`` (an ``*Export.cmake``) with any Python or numpy include directory replaced."""

    def fix(m: re.Match) -> str:
        dirs = []
        for d in m.group(2).split(";"):
            if _PYTHON_OR_NUMPY.match(d):
                d = numpy_include if "numpy" in d else python_include
            dirs.append(d)
        return m.group(1) + ";".join(dirs) + m.group(3)

    return _INCLUDES.sub(fix, text)


def fix_exports(prefix: str | Path = sys.prefix) -> list[Path]:
    """Point the wheels' exported CMake targets at this interpreter's headers; the files changed.

    Raises:
        BuildError: When this Python has no headers (``Python.h``) to compile against.
    """
    import numpy

    python_include = sysconfig.get_paths()["include"]
    if not Path(python_include, "Python.h").is_file():
        raise BuildError(
            f"no Python.h in {python_include}: the interface build needs the Python 3.11 "
            "headers (Debian: apt install python3.11-dev)"
        )
    changed = []
    for name in sorted(glob.glob(os.path.join(prefix, "share", "*", "cmake", "*Export.cmake"))):
        path = Path(name)
        text = path.read_text()
        new = rewrite_includes(text, python_include, numpy.get_include())
        if new == text:
            continue
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".fix-")
        with os.fdopen(fd, "w") as f:
            f.write(new)
        os.chmod(tmp, path.stat().st_mode & 0o777)
        os.replace(tmp, path)
        changed.append(path)
    return changed


def check_tools() -> None:
    """Cmake and a C compiler are on the path.

    Raises:
        BuildError: Naming the missing tool.
    """
    if shutil.which("cmake") is None:
        raise BuildError("cmake not found: make setup needs cmake (Debian: apt install cmake)")
    if not any(shutil.which(cc) for cc in ("cc", "gcc", "clang")):
        raise BuildError("no C compiler (cc, gcc or clang) found: make setup needs one")


def clean(build: Path = BUILD) -> None:
    """Remove what the previous build installed, and its build folder."""
    for manifest in build.glob("*/install_manifest.txt"):
        for line in manifest.read_text().splitlines():
            Path(line).unlink(missing_ok=True)
    shutil.rmtree(build, ignore_errors=True)


def build(packages: list[str], build: Path = BUILD) -> None:
    """colcon-build ``packages`` of ``ros2_ws/src`` into this venv's prefix.

    Raises:
        BuildError: When colcon fails (with the end of its output).
    """
    venv = Path(sys.prefix)
    env = dict(os.environ, AMENT_PREFIX_PATH=str(venv))  # CMake's ament index reads only this
    env["PATH"] = f"{venv / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    command = [
        str(venv / "bin" / "colcon"), "--log-base", str(build / "log"),
        "build", "--base-paths", str(SRC), "--packages-select", *packages,
        "--merge-install", "--install-base", str(venv), "--build-base", str(build),
        "--cmake-args", f"-DPython3_EXECUTABLE={sys.executable}",
        f"-DCMAKE_PREFIX_PATH={venv}", "-DBUILD_TESTING=OFF",
    ]  # fmt: skip
    result = subprocess.run(command, env=env, capture_output=True, text=True)
    if result.returncode != 0:
        raise BuildError(
            f"colcon build of {', '.join(packages)} failed:\n"
            + (result.stdout + result.stderr)[-4000:]
        )


def main(argv: list[str] | None = None) -> int:
    """Check the tools, fix the wheels' exports, rebuild the interface packages."""
    parser = argparse.ArgumentParser(prog="build_interfaces", description=__doc__.split("\n")[0])
    parser.add_argument("--check", action="store_true", help="only check cmake and a C compiler")
    args = parser.parse_args(argv)
    try:
        check_tools()
        if args.check:
            return 0
        fixed = fix_exports()
        packages = interface_packages()
        clean()
        build(packages)
    except BuildError as exc:
        print(f"build_interfaces: error: {exc}", file=sys.stderr)
        return 1
    print(
        f"build_interfaces: {', '.join(packages)} built into {sys.prefix} "
        f"({len(fixed)} wheel export file(s) fixed)"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
