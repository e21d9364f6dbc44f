"""Build script for the ``team_tick`` ament_python package."""

from glob import glob

from setuptools import find_packages, setup

package_name = "team_tick"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/config", glob("config/*")),
    ],
    install_requires=[
        "excavation_common",
        "blueprint_server",
        "blade_driver",
        "drive_executor",
        "excavation_sim",
        "numpy",
    ],
    zip_safe=True,
    maintainer="ANT excavation maintainers",
    maintainer_email="maintainers@ant-excavation.org",
    description="The team tick: the paper's timestep on a real team.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "team_tick = team_tick.node:main",
        ],
    },
)
