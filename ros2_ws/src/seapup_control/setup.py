from glob import glob

from setuptools import find_packages, setup

package_name = "seapup_control"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    package_data={package_name: ["data/*.yaml"]},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/config", glob("config/*.yaml")),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="seapup developers",
    maintainer_email="dev@seapup.invalid",
    description="Seapup autopilots: velocity controllers, self-test and supervisory hierarchy.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "open_loop = seapup_control.open_loop_node:main",
            "reference_schedule = seapup_control.reference_schedule_node:main",
            "self_test = seapup_control.self_test_node:main",
            "velocity_controller = seapup_control.velocity_controller_node:main",
            "mfol_velocity_controller = seapup_control.velocity_controller_node:main_mfol",
            "navigator = seapup_control.navigator_node:main",
            "position_controller = seapup_control.position_controller_node:main",
            "task_controller = seapup_control.task_controller_node:main",
            "controller_manager = seapup_control.controller_manager_node:main",
            "teleop = seapup_control.teleop_node:main",
        ],
        # control laws by name (seapup_common.controllers)
        "seapup.velocity_controllers": [
            "mfol = seapup_control.mfol_controller:MFOL_TYPE",
            "explicit = seapup_control.explicit:EXPLICIT_TYPE",
            "gmv = seapup_control.gmv:GMV_TYPE",
            "open_loop = seapup_control.profiles:OPEN_LOOP_TYPE",
            "manual = seapup_control.manual:MANUAL_TYPE",
        ],
    },
)
