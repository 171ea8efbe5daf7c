"""ament_python package definition; also a plain pip-installable distribution."""
from glob import glob

from setuptools import find_packages, setup

PACKAGE = "ltd_brake_ros"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test", "test.*", "benchmarks"]),
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/config", glob("config/*.yaml")),
    ] + [
        (f"share/{PACKAGE}/{folder}", glob(f"{folder}/*.yaml") + glob(f"{folder}/*.csv"))
        for folder in sorted(p.rstrip("/") for p in glob("config/*/"))
    ],
    python_requires=">=3.10",
    install_requires=[
        "numpy>=1.26,<3",
        "scipy>=1.11",
        "pyyaml>=6.0",
        "numba>=0.60",
    ],
    extras_require={
        "test": ["pytest>=8", "hypothesis>=6.100"],
    },
    zip_safe=True,
    maintainer="ltd_brake_ros maintainers",
    maintainer_email="maintainers@ltd-brake-ros.invalid",
    description="UIC air-brake longitudinal train dynamics as a ROS 2 plant",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "ltd-brake = ltd_brake_ros.cli.main:main",
            "sim_node = ltd_brake_ros.ros.sim_node:main",
            "replay_node = ltd_brake_ros.ros.replay_node:main",
        ],
    },
)
