from setuptools import find_packages, setup

package_name = "robotarium_safety"

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
    description="Barrier certificates and the always-on safety node.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "safety = robotarium_safety.safety_node:main",
        ],
    },
)
