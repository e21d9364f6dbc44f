"""Build script for the ``blade_driver`` ament_python package."""

from glob import glob

from setuptools import find_packages, setup

package_name = "blade_driver"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/config", glob("config/*")),
    ],
    install_requires=["pyserial", "pyyaml", "excavation_common", "numpy"],
    zip_safe=True,
    maintainer="ANT excavation maintainers",
    maintainer_email="maintainers@ant-excavation.org",
    description="Blade driver: behaviours to servo set-points, constant-force PID, watchdog.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "driver = blade_driver.driver_node:main",
            "fake_board = blade_driver.fake_board:main",
        ],
    },
)
