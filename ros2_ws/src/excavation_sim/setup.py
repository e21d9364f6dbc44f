"""Build script for the ``excavation_sim`` ament_python package."""

from glob import glob

from setuptools import find_packages, setup

package_name = "excavation_sim"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    package_data={package_name: ["soil_presets.yaml", "blade_forces.yaml"]},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/config", glob("config/*")),
    ],
    install_requires=[
        "numpy",
        "numba",
        "matplotlib",
        "ant_controller",
        "blueprint_server",
        "opencv-python-headless",
        "excavation_common",
        "overhead_localizer",
        "terrain_mapper",
        "pyyaml",
    ],
    zip_safe=False,
    maintainer="ANT excavation maintainers",
    maintainer_email="maintainers@ant-excavation.org",
    description="Simulated worksite: soil, bulldozer robots, blade model and fitness.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "sim = excavation_sim.sim_node:main",
            "sensors = excavation_sim.sensors_node:main",
            "dynamics = excavation_sim.dynamics_node:main",
        ],
    },
)
