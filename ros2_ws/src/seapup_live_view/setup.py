from glob import glob

from setuptools import find_packages, setup

package_name = "seapup_live_view"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/config", glob("config/*.yaml") + glob("config/*.json")),
    ],
    install_requires=["setuptools"],
    entry_points={"console_scripts": ["live_view = seapup_live_view.live_view_node:main"]},
    zip_safe=True,
    maintainer="seapup developers",
    maintainer_email="dev@seapup.invalid",
    description="Seapup live view: the graph served to Foxglove.",
    license="Apache-2.0",
)
