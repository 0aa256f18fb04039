from glob import glob

from setuptools import find_packages, setup

package_name = "seapup_sim"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    package_data={package_name: ["vehicles/*.yaml", "environment/*.yaml", "references/*.yaml"]},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/config", glob("config/*.yaml")),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="seapup developers",
    maintainer_email="dev@seapup.invalid",
    description="Seapup ROV vehicle and environment models and the simulator node.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "simulator = seapup_sim.simulator_node:main",
        ],
    },
)
