"""ament_python package: colcon builds it, pip installs it."""

from setuptools import find_packages, setup

PACKAGE = "sideslip_bags"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test", "tests"]),
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
    ],
    install_requires=["PyYAML", "rosbags", "mcap", "sideslip_msgs_py"],
    zip_safe=False,
    maintainer="sideslip maintainers",
    maintainer_email="maintainers@sideslip.invalid",
    description="Record and replay rosbag2 MCAP bags of the sideslip topics without the ROS 2 CLI.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "sideslip-record = sideslip_bags.record:main",
            "sideslip-play = sideslip_bags.play:main",
        ],
    },
)
