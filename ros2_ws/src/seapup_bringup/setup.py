from glob import glob

from setuptools import find_packages, setup

package_name = "seapup_bringup"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    package_data={package_name: ["cli_usage.json"]},   # ./seapup help's usage lines (cli_usage.py writes it)
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/config", glob("config/*.yaml") + glob("config/*.json")),
        ("share/" + package_name + "/launch", glob("launch/*.yaml")),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="seapup developers",
    maintainer_email="dev@seapup.invalid",
    description="Seapup bringup: graphs, the demo, the ./seapup commands and benchmarks.",
    license="Apache-2.0",
)
