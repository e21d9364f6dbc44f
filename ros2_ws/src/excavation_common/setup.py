"""Build script for the ``excavation_common`` ament_python package."""

from setuptools import find_packages, setup

package_name = "excavation_common"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    package_data={package_name: ["fastdds_profiles.xml", "fastdds_loopback.xml"]},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
    ],
    install_requires=["numpy", "pyyaml", "tqdm"],
    zip_safe=True,
    maintainer="ANT excavation maintainers",
    maintainer_email="maintainers@ant-excavation.org",
    description="Shared ROS layer: conversions, QoS, diagnostics, parameters, errors, constants.",
    license="Apache-2.0",
)
