from glob import glob

from setuptools import find_packages, setup

package_name = "seapup_common"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    package_data={package_name: ["data/*.yaml"]},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/config", glob("config/*.yaml") + glob("config/*.xml")),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="seapup developers",
    maintainer_email="dev@seapup.invalid",
    description="Seapup shared contract (pure), the only shared rclpy helpers and the bag recorder node.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "recorder = seapup_common.recorder_node:main",
        ],
        # control laws by name (seapup_common.controllers)
        "seapup.velocity_controllers": [
            "hold = seapup_common.controllers:HOLD_TYPE",
        ],
    },
)
