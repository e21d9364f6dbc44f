"""Build script for the ``excavation_field`` ament_python package."""

from setuptools import find_packages, setup

package_name = "excavation_field"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
    ],
    install_requires=[
        "excavation_bringup",
        "excavation_common",
        "excavation_sim",
        "ant_controller",
        "blueprint_server",
        "drive_executor",
        "terrain_mapper",
        "excavation_bags",
        "ant-evolution",
        "numpy",
        "matplotlib",
        "tqdm",
    ],
    zip_safe=True,
    maintainer="ANT excavation maintainers",
    maintainer_email="maintainers@ant-excavation.org",
    description="Section-6 field experiments, the field benchmark and the soak.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "ant-soak = excavation_field.soak:main",
            "ant-field-experiment = excavation_field.field_experiment:main",
            "ant-soil-study = excavation_field.soil_study:main",
        ],
    },
)
