"""Build script for the ``dome_emulator`` ament_python package."""

from setuptools import find_packages, setup

package_name = "dome_emulator"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
    ],
    install_requires=[
        "excavation_common",
        "blade_driver",
        "excavation_sim",
        "overhead_localizer",
        "terrain_mapper",
        "numpy",
        "opencv-python-headless",
    ],
    zip_safe=True,
    maintainer="ANT excavation maintainers",
    maintainer_email="maintainers@ant-excavation.org",
    description="Emulated dome drivers (base, servo board, camera, laser) for rehearsals.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "base = dome_emulator.base_node:main",
            "servo_board = dome_emulator.servo_board_node:main",
            "camera = dome_emulator.camera_node:main",
            "laser = dome_emulator.laser_node:main",
        ],
    },
)
