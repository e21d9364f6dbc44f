"""Build script for the ``blueprint_server`` ament_python package."""

from glob import glob

from setuptools import find_packages, setup

package_name = "blueprint_server"

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
        "opencv-python-headless",
        "excavation_common",
        "matplotlib",
    ],
    zip_safe=True,
    maintainer="ANT excavation maintainers",
    maintainer_email="maintainers@ant-excavation.org",
    description="Excavation blueprints: zones and goal depths from YAML, images and generators.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "blueprint_info = blueprint_server.blueprint_info:main",
            "server = blueprint_server.server_node:main",
        ],
    },
)
