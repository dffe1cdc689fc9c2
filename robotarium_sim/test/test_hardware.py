"""The hardware-like model (robotarium_sim.hardware), each effect measured on its own, and the whole
model's determinism. Plain numpy: no nodes."""
import numpy as np
import pytest

from robotarium_core import model
from robotarium_core.config import DEFAULT
from robotarium_sim.hardware import PWM_MAX, TICK, HardwareParameters, HardwareTestbed, Pipeline

ORIGIN = np.zeros((3, 1))


def drive(pipeline, v, w, seconds, every=0.033, robots=(0,)):
    """Send (v, w) every `every` s for `seconds`; return the true poses after each tick (ticks x 3 x N)."""
    trace = []
    period = int(round(every / TICK))
    for k in range(int(round(seconds / TICK))):
        if every and k % period == 0:
            pipeline.send(list(robots), [v] * len(robots), [w] * len(robots))
        pipeline.advance(1)
        trace.append(pipeline.true_poses.copy())
    return np.array(trace)


def pid_trace(pipeline, seconds, commands):
    """PWM and wheel speed of the left wheel at each tick; commands: {tick: (v, w)} sent then."""
    pwm, speed = [], []
    for k in range(int(round(seconds / TICK))):
        if k in commands:
            pipeline.send([0], [commands[k][0]], [commands[k][1]])
        pipeline.advance(1)
        pwm.append(pipeline.pwm[0, 0])
        speed.append(pipeline.wheel_speed[0, 0])
    return np.array(pwm), np.array(speed)


def wheels_only(**overrides):
    """The firmware's wheels (PID, slew, motor) with every other effect off."""
    return HardwareParameters.without_effects(ideal_wheels=False, pid_period=DEFAULT.pid_period, **overrides)


def test_wheel_step_response_is_limited_by_the_pwm_slew():
    # Full speed ahead (12.5 rad/s per wheel), then full speed back: the PI asks for a PWM change
    # of about 2.7 * 25 = 67 units in the first period of the reversal, the slew allows 50.
    commands = {k: (0.2, 0.0) for k in range(0, 600, 30)}
    commands.update({k: (-0.2, 0.0) for k in range(600, 1200, 30)})
    pwm, speed = pid_trace(Pipeline(ORIGIN, wheels_only(), seed=1), 1.2, commands)
    period = int(round(DEFAULT.pid_period / TICK))
    changes = np.diff(pwm[::period])
    assert np.abs(changes).max() == DEFAULT.pwm_slew            # never faster than the firmware's slew
    reversal = changes[60:]
    assert np.count_nonzero(reversal == -DEFAULT.pwm_slew) >= 3   # and it binds: 50 units per period, repeatedly
    assert 11.5 < speed[550] < 13.5 and -13.5 < speed[-1] < -11.5  # the PI holds the wheel near 12.5 rad/s

    # Without the limit the same reversal is faster: the slew is what shaped it.
    free_pwm, free_speed = pid_trace(Pipeline(ORIGIN, wheels_only(pwm_slew=2 * PWM_MAX), seed=1), 1.2, commands)
    assert np.abs(np.diff(free_pwm[::period])).max() > DEFAULT.pwm_slew
    crossed = np.argmax(speed[600:] < -10), np.argmax(free_speed[600:] < -10)
    assert crossed[0] > crossed[1]


def test_wheel_rise_time_and_firmware_stop_in_the_deadband():
    # From rest to 0.1 m/s (6.25 rad/s per wheel): no motion before the first PID period, about
    # 90 ms to 90 % (PI + motor lag), and motors off when the command falls into the deadband.
    commands = {k: (0.1, 0.0) for k in range(0, 500, 30)}
    commands.update({k: (0.00005, 0.005) for k in range(500, 800, 30)})
    pwm, speed = pid_trace(Pipeline(ORIGIN, wheels_only(), seed=2), 0.8, commands)
    rise = int(np.argmax(speed > 0.9 * 6.25))
    assert 40 < rise < 200
    assert pwm[-1] == 0 and abs(speed[-1]) < 0.05


def test_command_latency_is_a_delay_in_the_poses():
    # The same commands with and without 80 ms of command latency (a multiple of the 16 ms robot
    # loop): the trajectory is the same, 80 ticks later.
    lag = 0.080
    plain = drive(Pipeline(ORIGIN, HardwareParameters.without_effects(robot_loop_period=0.016), seed=3), 0.1, 0.5, 0.6)
    late = drive(Pipeline(ORIGIN, HardwareParameters.without_effects(robot_loop_period=0.016,
                                                                     command_latency=lag), seed=3), 0.1, 0.5, 0.6)
    shift = int(round(lag / TICK))
    assert np.array_equal(late[shift:], plain[:-shift])
    assert np.all(late[:shift] == 0)   # nothing moved before the first command arrived


def test_tracking_latency_delays_the_published_poses():
    lag = 0.05
    pipeline = Pipeline(ORIGIN, HardwareParameters.without_effects(tracking_latency=lag), seed=4)
    truth = drive(pipeline, 0.1, 0.0, 0.2)          # 200 ticks of true poses
    published = pipeline.measured()
    assert np.array_equal(published, truth[-1 - int(round(lag / TICK))])
    assert published[0, 0] == pytest.approx(0.1 * (0.2 - lag), abs=1e-4)


def test_deadband_switches_the_motors_off():
    params = HardwareParameters.without_effects()
    still = drive(Pipeline(ORIGIN, params, seed=5), 0.9 * DEFAULT.deadband_linear, 0.9 * DEFAULT.deadband_angular, 0.5)
    assert np.all(still == 0)
    creeping = drive(Pipeline(ORIGIN, params, seed=5), 2 * DEFAULT.deadband_linear, 0.0, 0.5)
    assert creeping[-1, 0, 0] == pytest.approx(2 * DEFAULT.deadband_linear * 0.5, rel=1e-6)
    turning = drive(Pipeline(ORIGIN, params, seed=5), 0.0, 2 * DEFAULT.deadband_angular, 0.5)
    assert turning[-1, 2, 0] == pytest.approx(2 * DEFAULT.deadband_angular * 0.5, rel=1e-6)


def test_brake_after_half_a_second_without_commands():
    pipeline = Pipeline(ORIGIN, HardwareParameters.without_effects(), seed=6)
    pipeline.send([0], [0.1], [0.0])
    pipeline.advance(int(round(2.0 / TICK)))
    assert pipeline.true_poses[0, 0] == pytest.approx(0.1 * (DEFAULT.brake_timeout + TICK), abs=1e-9)
    assert pipeline.brakes == 1


def test_the_robot_loop_passes_only_the_newest_command():
    params = HardwareParameters.without_effects(robot_loop_period=0.016)
    pipeline = Pipeline(ORIGIN, params, seed=7)
    loop = int(round(0.016 / TICK))
    pipeline.advance((pipeline.loop_phase - pipeline.t) % loop + 1)   # just after a loop tick
    for delay, v in ((0.0, 0.2), (0.005, 0.15), (0.010, 0.05)):      # three commands before the next one
        pipeline.send([0], [v], [0.0], delay=delay)
    pipeline.advance(loop)
    assert pipeline.target[0, 0] == 0.05                              # the last; 0.2 and 0.15 were never applied
    assert pipeline.true_poses[0, 0] == pytest.approx(0.05 * TICK, abs=1e-12)


def test_pose_noise_has_the_configured_spread():
    pipeline = Pipeline(np.zeros((3, 400)), HardwareParameters.without_effects(
        tracking_noise_position=0.002, tracking_noise_heading=0.01), seed=8)
    samples = np.array([pipeline.measured() for _ in range(50)])   # 20 000 draws per component
    assert np.std(samples[:, :2]) == pytest.approx(0.002, rel=0.05)
    assert np.std(samples[:, 2]) == pytest.approx(0.01, rel=0.05)
    assert abs(np.mean(samples[:, :2])) < 1e-4


def test_wheel_radius_spread_makes_open_loop_driving_curve():
    # Guide §2.2, Fig. 13: a constant forward command drives a straight line only in simulation.
    straight = drive(Pipeline(np.zeros((3, 20)), HardwareParameters.without_effects(), seed=9), 0.1, 0.0, 3.0,
                     robots=range(20))
    curved = drive(Pipeline(np.zeros((3, 20)), HardwareParameters.without_effects(wheel_radius_spread=0.01), seed=9),
                   0.1, 0.0, 3.0, robots=range(20))
    assert np.all(straight[-1, 1:] == 0)
    assert np.median(np.abs(curved[-1, 1])) > 0.002 and np.median(np.abs(curved[-1, 2])) > 0.02


def _hardware_run(seed, steps=150, n=6):
    poses = model.random_initial_conditions(n, np.random.default_rng(0))
    testbed = HardwareTestbed(poses, seed=seed)
    rng = np.random.default_rng(1)
    published = []
    for _ in range(steps):
        testbed.set_commands(np.arange(n), rng.uniform(-0.15, 0.15, n), rng.uniform(-2, 2, n))
        testbed.step()
        published.append(testbed.poses.copy())
    return np.array(published), testbed


def test_same_seed_same_run_bit_for_bit():
    first, testbed = _hardware_run(seed=11)
    again, _ = _hardware_run(seed=11)
    other, _ = _hardware_run(seed=12)
    assert np.array_equal(first, again)
    assert not np.array_equal(first, other)
    # and it is not the ideal testbed: latency, lag and noise make it differ from it
    ideal = model.Testbed(model.random_initial_conditions(6, np.random.default_rng(0)))
    rng = np.random.default_rng(1)
    for _ in range(150):
        ideal.set_commands(np.arange(6), rng.uniform(-0.15, 0.15, 6), rng.uniform(-2, 2, 6))
        ideal.step()
    assert np.abs(first[-1, :2] - ideal.poses[:2]).max() > 0.005
    assert "seed 11" in testbed.report() and "hardware" in testbed.report()


def test_the_report_names_the_mode_and_the_real_testbeds_robot_limit():
    ideal = model.debug_report(300, 0, 0, 0, number_of_robots=20)
    assert ideal == model.debug_report(300, 0, 0, 0)   # the rps text, untouched, up to 20 robots
    many = model.debug_report(300, 0, 0, 0, number_of_robots=21)
    assert "uses 21 robots, but the real Robotarium deploys at most 20" in many
    assert many.index("approximately 10 real seconds") < many.index("21 robots") < many.index("No errors")
    hardware = model.debug_report(300, 0, 0, 0, hardware_seed=5)
    assert "simulated the real testbed's hardware" in hardware and "seed 5" in hardware
