from setuptools import find_packages, setup

package_name = "robotarium_core"

setup(
    name=package_name,
    version="0.2.0",
    packages=find_packages(exclude=["test"]),
    package_data={package_name: ["*.yaml", "*.xml"]},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/config", ["robotarium_core/testbed.yaml"]),
    ],
    install_requires=["setuptools"],
    extras_require={"test": ["pytest"]},   # test/ (colcon test runs it with pytest)
    zip_safe=False,
    maintainer="Robotarium ROS team",
    maintainer_email="robotarium-ros@example.com",
    description=("The ground floor of the Robotarium testbed: the arena and GTernal model (plain numpy), the one "
                 "testbed configuration, argument checks, topic names and QoS, node helpers. No nodes."),
    license="Apache-2.0",
    entry_points={
        "console_scripts": [

        ],
    },
)
