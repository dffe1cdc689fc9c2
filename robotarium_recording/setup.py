from setuptools import find_packages, setup

package_name = "robotarium_recording"

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
    zip_safe=False,
    maintainer="Robotarium ROS team",
    maintainer_email="robotarium-ros@example.com",
    description=("Recording of Robotarium runs: rosbag2/MCAP bag I/O, the recorder and replay nodes, and the "
                 "results of a run (report, plot, video)."),
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "recorder = robotarium_recording.recorder_node:main",
            "replay = robotarium_recording.replay_node:main",
            "view = robotarium_recording.view_node:main",
        ],
    },
)
