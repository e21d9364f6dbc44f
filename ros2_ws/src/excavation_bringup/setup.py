"""Build script for the ``excavation_bringup`` ament_python package."""

from glob import glob

from setuptools import find_packages, setup

package_name = "excavation_bringup"

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
        "ant_controller",
        "blueprint_server",
        "excavation_sim",
        "overhead_localizer",
        "terrain_mapper",
        "blade_driver",
        "team_supervisor",
        "drive_executor",
        "team_tick",
        "excavation_bags",
        "numpy",
        "websockets",
        "libfaketime",
        "pyyaml",
        "foxglove-sdk",
    ],
    zip_safe=True,
    maintainer="ANT excavation maintainers",
    maintainer_email="maintainers@ant-excavation.org",
    description="Trials and the dome: ant-trial, site files, ant-dome, the live view.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "ant-trial = excavation_bringup.trial:main",
            "ant-dome = excavation_bringup.dome:main",
            "ant-view = excavation_bringup.view:main",
        ],
    },
)
