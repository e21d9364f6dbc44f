"""Build script for the ``ant_controller`` ament_python package."""

from glob import glob

from setuptools import find_packages, setup

package_name = "ant_controller"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/config", glob("config/*")),
    ],
    install_requires=["numpy", "numba", "excavation_common"],
    zip_safe=True,
    maintainer="ANT excavation maintainers",
    maintainer_email="maintainers@ant-excavation.org",
    description="ANT controller core: genome, tissue, sensing, behaviours, hand-coded rules.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "genome_info = ant_controller.genome_info:main",
            "controller = ant_controller.controller_node:main",
        ],
    },
)
