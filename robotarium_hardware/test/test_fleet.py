"""The fleet file: defaults, checks that name the bad field, the calibration, the round trip."""
import math

import numpy as np
import pytest

from robotarium_hardware import fleet as fleets
from robotarium_hardware.sim_fleet import MOCAP_FRAME, fleet_of, start_poses


def test_a_minimal_fleet_file_takes_every_default_from_one_place():
    fleet = fleets.from_dict({"robots": ["r0", {"name": "r1", "cmd_type": "TwistStamped"}]})
    assert fleet.tracking == "mocap" and fleet.names == ["r0", "r1"]
    assert fleet.cmd_topic(fleet.robots[0]) == "/r0/cmd_vel"
    assert fleet.pose_topic(fleet.robots[1]) == "/vrpn_mocap/r1/pose"
    assert fleet.robots[1].cmd_type == "TwistStamped" and fleet.calibration == fleets.Calibration()


@pytest.mark.parametrize("document, words", [
    ({}, "needs robots"),
    ({"robots": [{"name": "r0", "cmd_type": "Foo"}]}, "robots[0].cmd_type must be Twist or TwistStamped"),
    ({"robots": [{"name": "r0", "speed": 3}]}, "robots[0] has unknown field(s) speed"),
    ({"robots": ["r0", "r0"]}, "r0 appear(s) more than once"),
    ({"robots": ["r0"], "tracking": "lidar"}, "tracking must be mocap or camera"),
    ({"robots": ["r0"], "tracking": "camera"}, "robots[0] (r0) needs a tag"),
    ({"robots": ["r0"], "lost_after": float("nan")}, "lost_after must be a finite number"),
    ({"robots": ["r0"], "calibration": {"x": 0, "yaw": "a"}}, "calibration.yaw must be a finite number"),
    ({"robots": [{"name": "r0", "cmd_topic": "not a topic"}]}, "robots[0].cmd_topic must be a ROS topic name"),
])
def test_a_bad_fleet_file_is_refused_naming_the_field(document, words):
    with pytest.raises(fleets.FleetError) as error:
        fleets.from_dict(document)
    assert words in str(error.value)


def test_load_names_the_file(tmp_path):
    path = tmp_path / "fleet.yaml"
    path.write_text("robots: [{name: r0, cmd_type: Foo}]\n")
    with pytest.raises(fleets.FleetError, match="fleet.yaml: robots.0..cmd_type"):
        fleets.load(str(path))
    with pytest.raises(fleets.FleetError, match="cannot read"):
        fleets.load(str(tmp_path / "none.yaml"))


def test_the_calibration_takes_tracking_poses_to_the_arena_and_back():
    c = fleets.Calibration(x=-1.6, y=-1.0, yaw=0.3, scale=1.0)
    x, y, theta = c.to_arena(*c.from_arena(np.array([0.5, -1.2]), np.array([0.2, 0.7]), np.array([3.0, -0.4])))
    assert np.allclose(x, [0.5, -1.2]) and np.allclose(y, [0.2, 0.7]) and np.allclose(theta, [3.0, -0.4])
    # the tracking frame's origin is (x, y) in the arena, its x axis turned by yaw
    ax, ay, at = c.to_arena(1.0, 0.0, 0.0)
    assert math.isclose(ax, -1.6 + math.cos(0.3)) and math.isclose(ay, -1.0 + math.sin(0.3)) and math.isclose(at, 0.3)


def test_a_simulated_fleets_file_reads_back_as_it_was_written(tmp_path):
    fleet = fleet_of(4, "mocap")
    path = tmp_path / "fleet.yaml"
    path.write_text(fleet.to_yaml())
    again = fleets.load(str(path))
    assert again == fleet and again.calibration == MOCAP_FRAME
    assert [r.cmd_type for r in again.robots] == ["Twist", "TwistStamped", "Twist", "TwistStamped"]
    poses = start_poses(12)
    assert poses.shape == (3, 12) and np.min(np.abs(poses[0])) < 1.6 and np.all(np.abs(poses[1]) < 1.0)
