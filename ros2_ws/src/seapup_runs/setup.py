from setuptools import find_packages, setup

package_name = "seapup_runs"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    package_data={package_name: ["data/*.yaml", "data/specs/*.yaml", "data/campaigns/*.yaml"]},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="seapup developers",
    maintainer_email="dev@seapup.invalid",
    description="Seapup run layer: run specifications and results as data, the in-process runner.",
    license="Apache-2.0",
)
