"""Build script for the ``team_supervisor`` ament_python package."""

from glob import glob

from setuptools import find_packages, setup

package_name = "team_supervisor"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/config", glob("config/*")),
    ],
    install_requires=["excavation_common"],
    zip_safe=True,
    maintainer="ANT excavation maintainers",
    maintainer_email="maintainers@ant-excavation.org",
    description="Team supervisor: e-stop, heartbeat, pause/resume, per-robot enable, lost robots.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "supervisor = team_supervisor.supervisor_node:main",
            "ant-operator = team_supervisor.operator:main",
        ],
    },
)
