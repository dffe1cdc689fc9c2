"""The safety node's margins for the hardware-like mode (issue 36): where commands act late
(tracking and command latency, the robots' loop, the wheels' lag: ArmSafety.latency), the testbed's
certificate widens what it keeps by what a robot covers meanwhile. The adversarial scenes of the
safety guarantee's tests, driven through the hardware-like model (robotarium_sim.hardware) with
the certificate armed as the simulator arms it: no two robots ever come within robot_diameter,
none leaves the arena, measured on the robots' true poses. Without the latency the same scenes
collide, so the margin is what holds them. Plain numpy, no ROS."""
import os
import sys

import numpy as np
import pytest

from robotarium_core import model
from robotarium_core.config import DEFAULT
from robotarium_safety.guard import filter_commands
from robotarium_safety.testbed_certificate import TestbedCertificate
from robotarium_sim.hardware import HardwareTestbed

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "robotarium_safety",
                                "test"))
import test_safety_guarantee as guarantee  # noqa: E402

SCENES = {
    "crowd of 20 pursuing": (("crowd", 20, 0.2, 3), ("pursue",)),
    "crowd of 20 reversing": (("crowd", 20, 0.2, 3), ("reverse",)),
    "head-on at full speed": (("pair", 0.4, 0.0, 0.0, np.pi), ("constant", 0.2, 0.0)),
    "into a corner": (("wall", 6, 0.08, "corner", 1), ("constant", 0.2, 0.0)),
    "to goals packed 0.2 m apart": (("crowd", 20, 0.2, 3), ("goals", 4)),
}


def run_hardware_like(scene, script, latency, steps=200, seed=7):
    """(closest true centre distance, how far the farthest true centre got beyond the arena)."""
    testbed = HardwareTestbed(guarantee.make_scene(scene), DEFAULT, seed=seed)
    certificate = TestbedCertificate(DEFAULT, latency=latency, real_time=True)
    drive = guarantee.make_script(script)
    n = testbed.number_of_robots
    closest, outside = np.inf, -np.inf
    for k in range(steps):
        seen = testbed.poses.copy()   # what the tracker published: late and noisy
        safe = filter_commands(certificate, np.array(drive(k, seen), dtype=float).reshape(2, n), seen, DEFAULT).safe
        testbed.set_commands(np.arange(n), safe[0], safe[1], now=k * DEFAULT.time_step)
        testbed.step()
        true = testbed.pipeline.true_poses
        closest = min(closest, guarantee.closest_pair(true))
        x_min, x_max, y_min, y_max = DEFAULT.arena
        outside = max(outside, float(np.max([x_min - true[0], true[0] - x_max, y_min - true[1], true[1] - y_max])))
    return closest, outside


@pytest.mark.parametrize("name", list(SCENES))
def test_the_latency_margin_keeps_hardware_like_robots_apart_and_inside(name):
    latency = HardwareTestbed(np.zeros((3, 1)), DEFAULT, seed=1).latency
    assert 0.1 < latency < 0.3   # tracking, network, the robots' loop and the wheels (testbed.yaml)
    closest, outside = run_hardware_like(*SCENES[name], latency)
    assert closest > DEFAULT.robot_diameter, "true centres %.4f m apart" % closest
    assert outside < 0, "a true centre %.4f m outside the arena" % outside


def test_without_the_latency_margin_hardware_like_robots_collide():
    """The test above has teeth: armed as for the ideal simulator, the same pipeline collides."""
    closest = min(run_hardware_like(*SCENES[name], 0.0)[0] for name in ("crowd of 20 pursuing", "head-on at full speed"))
    assert closest <= DEFAULT.robot_diameter


def test_the_arena_declares_its_latency_to_the_safety_node():
    """The ideal testbed has none; the hardware-like one its pipeline's (ArmSafety.latency)."""
    assert model.Testbed(np.zeros((3, 1))).latency == 0.0
    hardware = HardwareTestbed(np.zeros((3, 1)), DEFAULT, seed=1)
    p = hardware.pipeline.params
    assert hardware.latency == pytest.approx(p.tracking_latency + p.command_latency + p.command_jitter
                                             + p.robot_loop_period + 6 * p.pid_period + 3 * p.motor_time_constant)
