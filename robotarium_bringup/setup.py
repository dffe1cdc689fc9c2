from setuptools import find_packages, setup

package_name = "robotarium_bringup"

setup(
    name=package_name,
    version="0.2.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/launch", ["launch/testbed.launch.py"]),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="Robotarium ROS team",
    maintainer_email="robotarium-ros@example.com",
    description="Starting a Robotarium testbed: launch file, local testbeds, the registry of running ones.",
    license="Apache-2.0",
)
