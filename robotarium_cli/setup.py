from setuptools import find_packages, setup

from robotarium_cli.verb import VERBS  # imports nothing else

package_name = "robotarium_cli"

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
    description="The robotarium command: robotarium VERB, and ros2 robotarium VERB where ros2cli is installed.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": ["robotarium = robotarium_cli.main:console_main"],
        "ros2cli.command": ["robotarium = robotarium_cli.command.robotarium:RobotariumCommand"],
        "robotarium_cli.verb": ["%s = robotarium_cli.command.robotarium:%sVerb" % (verb, verb.capitalize())
                                for verb in VERBS],
    },
)
