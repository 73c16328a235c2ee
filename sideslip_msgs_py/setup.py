"""Install sideslip_msgs_py with setuptools (colcon's ament_python and pip both use this)."""

from setuptools import find_packages, setup

PACKAGE = "sideslip_msgs_py"

setup(
    name=PACKAGE,
    version="0.1.0",
    # find_packages, not [PACKAGE]: the rclpy plumbing lives in the sub-package `nodes`.
    packages=find_packages(exclude=["test", "tests"]),
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
    ],
    install_requires=["numpy"],
    zip_safe=True,
    maintainer="sideslip maintainers",
    maintainer_email="maintainers@sideslip.invalid",
    description="Sideslip wire contract: topics, QoS, message field mapping, rosbag2 helpers.",
    license="Apache-2.0",
    python_requires=">=3.11",
)
