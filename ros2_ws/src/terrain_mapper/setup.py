"""Build script for the ``terrain_mapper`` ament_python package."""

from glob import glob

from setuptools import find_packages, setup

package_name = "terrain_mapper"

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
        "numpy",
        "pyyaml",
        "matplotlib",
        "blueprint_server",
        "excavation_common",
        "rosbags",
    ],
    zip_safe=True,
    maintainer="ANT excavation maintainers",
    maintainer_email="maintainers@ant-excavation.org",
    description="Overhead laser scans to a per-cell height map; field metrics between two maps.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "mapper = terrain_mapper.mapper_node:main",
            "field-metrics = terrain_mapper.field_metrics:main",
            "calibrate_mount = terrain_mapper.calibrate_mount:main",
        ],
    },
)
