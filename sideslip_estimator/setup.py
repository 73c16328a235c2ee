"""ament_python package: colcon builds it, pip installs it."""

from glob import glob

from setuptools import find_packages, setup

PACKAGE = "sideslip_estimator"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test", "tests"]),
    package_data={
        PACKAGE: ["data/single_track/*.yaml", "data/ukf/*.yaml", "data/models/*.safetensors"]
    },
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/config", glob("config/*.yaml")),
        (f"share/{PACKAGE}/launch", glob("launch/*.launch.xml")),
    ],
    # scipy: the Y_a check's filters (imu_scale.mode, on by default).
    install_requires=["numpy", "PyYAML", "scipy", "sideslip_msgs_py"],
    # Optional back-ends: `pip install sideslip_estimator[pso_lstm]` (the model file reader
    # and numba for the compiled streaming engine), `[torch]` for the torch engine, `[ukf]`.
    extras_require={
        "pso_lstm": ["safetensors", "numba"],
        "torch": ["torch", "safetensors"],
        "ukf": ["filterpy", "scipy"],
    },
    zip_safe=False,
    maintainer="sideslip maintainers",
    maintainer_email="maintainers@sideslip.invalid",
    description="Sideslip-angle estimator node and model back-ends.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "estimator_node = sideslip_estimator.node:main",
            "sideslip-estimator = sideslip_estimator.node:main",
            "sideslip-watch = sideslip_estimator.tools.watch:main",
        ],
    },
)
