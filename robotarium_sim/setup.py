from glob import glob

from setuptools import find_packages, setup

package_name = "robotarium_sim"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/config", glob("config/*.yaml")),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="Robotarium ROS team",
    maintainer_email="robotarium-ros@example.com",
    description="Robotarium arena and GTernal model, simulator node, recorder and replay.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "simulator = robotarium_sim.simulator_node:main",
            "recorder = robotarium_sim.recorder_node:main",
            "replay = robotarium_sim.replay_node:main",
        ],
    },
)
