"""Build script for the ``drive_executor`` ament_python package."""

from glob import glob

from setuptools import find_packages, setup

package_name = "drive_executor"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/config", glob("config/*")),
    ],
    install_requires=["excavation_common", "numpy"],
    zip_safe=True,
    maintainer="ANT excavation maintainers",
    maintainer_email="maintainers@ant-excavation.org",
    description="Behaviour words to wheel motion (cmd_vel), closed loop on the pose.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "executor = drive_executor.executor_node:main",
        ],
    },
)
