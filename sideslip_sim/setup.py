"""ament_python package: colcon builds it, pip installs it."""

from glob import glob

from setuptools import find_packages, setup

PACKAGE = "sideslip_sim"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test", "tests"]),
    package_data={PACKAGE: ["data/vehicles/*.yaml", "data/tires/*.tir"]},
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/vehicles", glob(f"{PACKAGE}/data/vehicles/*.yaml")),
        (f"share/{PACKAGE}/tires", glob(f"{PACKAGE}/data/tires/*.tir")),
        (f"share/{PACKAGE}/config", glob("config/*.yaml")),
        (f"share/{PACKAGE}/launch", glob("launch/*.launch.xml")),
    ],
    install_requires=["numpy", "numba", "PyYAML", "tqdm", "rosbags", "sideslip_msgs_py"],
    zip_safe=False,
    maintainer="sideslip maintainers",
    maintainer_email="maintainers@sideslip.invalid",
    description="Full-vehicle simulator and labelled bag generator for sideslip estimation.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "sideslip-generate = sideslip_sim.generate_cli:main",
            # `ros2 run sideslip_sim sim_node` and the pip console script are one program.
            "sim_node = sideslip_sim.node:main",
            "sideslip-sim = sideslip_sim.node:main",
        ],
    },
)
