from setuptools import find_packages, setup

package_name = "robotarium_client"

setup(
    name=package_name,
    version="0.2.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="Robotarium ROS team",
    maintainer_email="robotarium-ros@example.com",
    description="The Robotarium Python API over ROS 2 topics and the rps import path.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [

        ],
    },
)
