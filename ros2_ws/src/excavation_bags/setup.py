"""Build script for the ``excavation_bags`` ament_python package."""

from glob import glob

from setuptools import find_packages, setup

package_name = "excavation_bags"

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
        "excavation_sim",
        "overhead_localizer",
        "drive_executor",
        "numpy",
        "pyyaml",
        "matplotlib",
        "pillow",
        "tqdm",
        "rosbags",
        "mcap",
        "terrain_mapper",
        "opencv-python-headless",
    ],
    zip_safe=True,
    maintainer="ANT excavation maintainers",
    maintainer_email="maintainers@ant-excavation.org",
    description="Bags (rosbag2 directories, MCAP storage): record, play, recover, report.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "ant-bag = excavation_bags.cli:main",
        ],
    },
)
