"""ament_python package definition; also a plain pip-installable distribution."""
import re
from glob import glob

from setuptools import find_packages, setup

PACKAGE = "ltd_brake_ros"
# the one version: ltd_brake_ros/_version.py (package.xml repeats it; a test keeps them equal)
with open(f"{PACKAGE}/_version.py", encoding="utf-8") as f:
    VERSION = re.search(r'^__version__ = "([^"]+)"', f.read(), re.M).group(1)

setup(
    name=PACKAGE,
    version=VERSION,
    packages=find_packages(exclude=["test", "test.*", "benchmarks"]),
    package_data={PACKAGE: ["py.typed"], f"{PACKAGE}.recording": ["message_definitions.json"]},
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml", "LICENSE", "CHANGELOG.md"]),
        (f"share/{PACKAGE}/config", glob("config/*.yaml")),
        # ros2 launch ltd_brake_ros <file>; Foxglove and PlotJuggler layouts
        (f"share/{PACKAGE}/launch", sorted(glob("launch/*.launch.*"))),
        (f"share/{PACKAGE}/layouts", sorted(glob("layouts/*.json") + glob("layouts/*.xml"))),
    ] + [
        (f"share/{PACKAGE}/{folder}", glob(f"{folder}/*.yaml") + glob(f"{folder}/*.csv"))
        for folder in sorted(p.rstrip("/") for p in glob("config/*/"))
    ],
    python_requires=">=3.10",
    # every runtime import of the library and of ltd-brake (simulate, validate, calibrate,
    # report, recover); requirements.txt pins the versions tested
    install_requires=[
        "numpy>=1.26,<3",
        "scipy>=1.11",
        "pyyaml>=6.0",
        "numba>=0.60",
        "matplotlib>=3.8",  # report: plots
        "tqdm>=4.66",  # calibrate: progress bar
        "mcap>=1.6,<2",  # recording: MCAP records, reading
        "zstandard>=0.22",  # recording: zstd chunks
        "lz4>=4.3",  # recording: lz4 chunks
        "pandas>=2.1",  # the Python API: time series and campaign results as DataFrames
        "xarray>=2024.1",  # the Python API: time series as Datasets
    ],
    extras_require={
        # the ROS 2 Jazzy wheels the nodes need (sim_node, replay_node); a ROS install gets
        # them from package.xml instead
        "ros": [
            "ros-jazzy-rclpy>=7.1,<8",
            "ros-jazzy-common-interfaces>=5.3,<6",
            "ros-jazzy-rosgraph-msgs>=2.0,<3",
            "ros-jazzy-nav-msgs>=5.3,<6",
            "ros-jazzy-rmw-fastrtps-cpp>=8.4,<9",
        ],
        # ltd-brake campaign: Dask distributed executor, Parquet results, SALib (the sobol and
        # morris designs and their sensitivity indices; a design's sample is SALib 1.6's)
        "campaign": ["dask[distributed]>=2024.1", "pyarrow>=14", "salib>=1.6,<1.7"],
        # the Python API's time series as Parquet files
        "analysis": ["pyarrow>=14"],
        # the documentation site (mkdocs build)
        "docs": ["mkdocs>=1.6", "mkdocs-material>=9.5", "mkdocstrings>=0.25",
                 "mkdocstrings-python>=1.10"],
        "test": ["pytest>=8", "pytest-timeout>=2.3", "hypothesis>=6.100", "rosbags>=0.10",
                 "mcap-ros2-support>=0.5"],
    },
    # the closed-loop example, which trains.launch.py starts (colcon: lib/ltd_brake_ros, pip: bin)
    scripts=glob("examples/speed_controller.py"),
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
