from setuptools import find_packages, setup

package_name = "robotarium_hardware"

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
    description="A Robotarium of your own robots: the hardware arena node, the tag tracker, a simulated fleet.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "arena = robotarium_hardware.arena_node:main",
            "tag_tracker = robotarium_hardware.tag_tracker_node:main",
            "robot = robotarium_hardware.robot_node:main",
            "mocap = robotarium_hardware.mocap_node:main",
            "camera = robotarium_hardware.camera_node:main",
            "fleet = robotarium_hardware.sim_fleet:main",
        ],
    },
)
