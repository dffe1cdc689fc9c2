from setuptools import find_packages, setup

package_name = "robotarium_sim"

setup(
    name=package_name,
    version="0.2.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
    ],
    install_requires=["setuptools"],
    extras_require={"test": ["pytest"]},   # test/ (colcon test runs it with pytest)
    zip_safe=True,
    maintainer="Robotarium ROS team",
    maintainer_email="robotarium-ros@example.com",
    description="The Robotarium simulator node.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "simulator = robotarium_sim.simulator_node:main",
        ],
    },
)
