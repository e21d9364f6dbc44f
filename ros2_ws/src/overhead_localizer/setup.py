"""Build script for the ``overhead_localizer`` ament_python package."""

from glob import glob

from setuptools import find_packages, setup

package_name = "overhead_localizer"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/config", glob("config/*")),
    ],
    install_requires=["numpy", "pyyaml", "opencv-python-headless", "excavation_common"],
    zip_safe=True,
    maintainer="ANT excavation maintainers",
    maintainer_email="maintainers@ant-excavation.org",
    description="Overhead camera LED beacons to robot poses; camera calibration.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "localizer = overhead_localizer.localizer_node:main",
            "calibrate = overhead_localizer.calibrate:main",
        ],
    },
)
