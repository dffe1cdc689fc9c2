"""The hardware-like mode: the real pipeline between a script's commands and the GTernal's
wheels, and between the robots and the poses the script sees. Plain numpy, no ROS.

Where the ideal testbed (robotarium_core.model.Testbed, as rps) applies a command for exactly one
step and hands back exact poses, this models command latency and jitter, the robot's 16 ms loop,
the GTernal firmware's deadband, wheel-speed PI, PWM slew and brake, the motors' lag, unequal
wheels, and tracking latency and noise. Every stage is a parameter of the testbed configuration
(with its source); the model runs on a clock of TICK = 1 ms with one Generator seeded per
experiment, so a lockstep run is the same bit for bit for the same seed.
The pipeline, the firmware it follows and what it simplifies: docs/hardware.md.
"""
import collections
import dataclasses
import math
import secrets

import numpy as np

from robotarium_core import model
from robotarium_core.config import DEFAULT

TICK = 0.001   # s: the model's clock
PWM_MAX = 255  # the Teensy's analogWrite range, +-


@dataclasses.dataclass(frozen=True)
class HardwareParameters:
    """The hardware-like model's numbers (see testbed.yaml for the meaning and source of each).

    ideal_wheels is not a testbed setting: True makes each wheel take its target speed at once
    (no PID, slew, motor lag or encoder), to look at the other effects alone."""
    tracking_latency: float = DEFAULT.tracking_latency
    tracking_noise_position: float = DEFAULT.tracking_noise_position
    tracking_noise_heading: float = DEFAULT.tracking_noise_heading
    command_latency: float = DEFAULT.command_latency
    command_jitter: float = DEFAULT.command_jitter
    robot_loop_period: float = DEFAULT.robot_loop_period
    pid_period: float = DEFAULT.pid_period
    pid_kp: float = DEFAULT.pid_kp
    pid_ki: float = DEFAULT.pid_ki
    pwm_slew: int = DEFAULT.pwm_slew
    encoder_counts: int = DEFAULT.encoder_counts
    motor_free_speed: float = DEFAULT.motor_free_speed
    motor_time_constant: float = DEFAULT.motor_time_constant
    deadband_linear: float = DEFAULT.deadband_linear
    deadband_angular: float = DEFAULT.deadband_angular
    brake_timeout: float = DEFAULT.brake_timeout
    wheel_radius_spread: float = DEFAULT.wheel_radius_spread
    ideal_wheels: bool = False

    @classmethod
    def from_config(cls, config=DEFAULT):
        return cls(**{f.name: getattr(config, f.name) for f in dataclasses.fields(cls) if hasattr(config, f.name)})

    @property
    def latency(self):
        """s from the poses a command is filtered at until the wheels obey it: the tracker's and
        the network's latency and jitter, the robot's loop, the PWM slewing from full to zero, and
        three motor time constants. The safety node widens its margins by the distance a robot
        covers in it (ArmSafety.latency)."""
        slewing = math.ceil(PWM_MAX / max(self.pwm_slew, 1)) * self.pid_period
        return (self.tracking_latency + self.command_latency + self.command_jitter + self.robot_loop_period
                + slewing + 3 * self.motor_time_constant)

    @classmethod
    def without_effects(cls, **effects):
        """Every effect off (no latency, noise, jitter, slip; loops every tick; ideal wheels),
        except those given: to measure one effect in isolation."""
        off = dict(tracking_latency=0.0, tracking_noise_position=0.0, tracking_noise_heading=0.0,
                   command_latency=0.0, command_jitter=0.0, robot_loop_period=TICK, pid_period=TICK,
                   wheel_radius_spread=0.0, ideal_wheels=True)
        off.update(effects)
        return cls(**off)


def ticks(seconds):
    """Whole ticks of the model's clock in `seconds` (at least 0)."""
    return max(0, int(round(seconds / TICK)))


class Pipeline:
    """N GTernals behind the real testbed's pipeline, on a 1 ms clock.

    send() hands a command to the network at a moment of the current step; advance() runs the
    clock; measured() gives the poses the tracking system publishes now. `true_poses` are where
    the robots really are.

    The robots' loops share one phase (drawn per run): per-robot phases would differ by less than
    a loop period, a spread the command jitter already gives. So the discrete work happens on few
    ticks (an arrival, a robot loop with a new command, a PID period, a brake) and the motion in
    between is computed for all its ticks at once (the wheel speeds' lag in closed form, the poses
    tick by tick with cumulative sums): a 33-tick step costs about as much as a handful of ticks.
    """

    def __init__(self, poses, params=HardwareParameters(), seed=0, wheel_radius=DEFAULT.wheel_radius,
                 base_length=DEFAULT.base_length):
        p = self.params = params
        self.rng = np.random.default_rng(seed)
        self.true_poses = np.array(poses, dtype=float)
        n = self.number_of_robots = self.true_poses.shape[1]
        self.wheel_radius, self.base_length = wheel_radius, base_length
        self.t = 0   # ticks since the start
        self._loop_ticks, self._pid_ticks = max(1, ticks(p.robot_loop_period)), max(1, ticks(p.pid_period))
        self._latency, self._jitter = ticks(p.command_latency), ticks(p.command_jitter)
        self._brake = ticks(p.brake_timeout)
        self._pid_seconds = self._pid_ticks * TICK
        self._decay = 0.0 if p.motor_time_constant == 0 else np.exp(-TICK / p.motor_time_constant)
        # The fleet's loop phases and each wheel's radius (left row 0, right row 1), fixed for the run.
        self.loop_phase = int(self.rng.integers(0, self._loop_ticks))
        self.pid_phase = int(self.rng.integers(0, self._pid_ticks))
        spread = np.clip(self.rng.standard_normal((2, n)), -3, 3) * p.wheel_radius_spread
        self.radii = wheel_radius * (1 + spread)

        # The network: commands in flight, in the order they were sent: [arrival ticks, pending, v/w].
        self._in_flight = collections.deque()
        self._next_arrival = np.inf
        self._last_arrival = np.full(n, -1, dtype=np.int64)
        # The robot's Raspberry Pi: the newest command that arrived, not yet passed on.
        self._inbox = np.zeros((2, n))
        self._inbox_new = np.zeros(n, dtype=bool)
        # The Teensy: the (v, omega) it follows and when a command last came (none yet: braked).
        self.target = np.zeros((2, n))
        self._last_command = np.full(n, -self._brake - 1, dtype=np.int64)
        self._brake_at = np.inf   # first tick at which some robot may brake
        self.brakes = 0           # times a robot braked for want of commands
        # Wheels (row 0 left, row 1 right): PWM computed / applied, PI state, speed, angle, encoder.
        self.pwm = np.zeros((2, n))
        self.pwm_applied = np.zeros((2, n))
        self._integral = np.zeros((2, n))
        self._driving = np.zeros(n, dtype=bool)
        self.wheel_speed = np.zeros((2, n))
        self._angle = np.zeros((2, n))
        self._counts_before = np.zeros((2, n))
        # The true poses of the last tracking_latency + 1 ticks (a ring: row t % length is tick t);
        # the tracker publishes the oldest.
        self._history = np.repeat(self.true_poses[None], ticks(p.tracking_latency) + 1, axis=0)

    # -- the network -------------------------------------------------------------------------------

    def send(self, ids, v, w, delay=0.0):
        """Commands (v, omega) for robots `ids`, sent `delay` s after the current tick. Each robot's
        copy arrives after command_latency plus its own jitter, never before an earlier one (TCP)."""
        ids = np.asarray(ids, dtype=int)
        if ids.size == 0:
            return
        sent = self.t + ticks(delay)
        arrival = np.zeros(self.number_of_robots, dtype=np.int64)
        jitter = self.rng.integers(0, self._jitter + 1, ids.size) if self._jitter else 0
        arrival[ids] = np.maximum(sent + self._latency + jitter, self._last_arrival[ids])
        self._last_arrival[ids] = arrival[ids]
        pending = np.zeros(self.number_of_robots, dtype=bool)
        pending[ids] = True
        velocities = np.zeros((2, self.number_of_robots))
        velocities[0, ids], velocities[1, ids] = v, w
        self._in_flight.append([arrival, pending, velocities])
        self._next_arrival = min(self._next_arrival, int(arrival[ids].min()))

    def _deliver(self):
        for arrival, pending, velocities in self._in_flight:
            due = pending & (arrival <= self.t)
            if due.any():
                self._inbox[:, due] = velocities[:, due]
                self._inbox_new |= due
                pending &= ~due
        while self._in_flight and not self._in_flight[0][1].any():
            self._in_flight.popleft()
        self._next_arrival = min((int(a[p].min()) for a, p, _ in self._in_flight), default=np.inf)

    # -- the robot ---------------------------------------------------------------------------------

    def _active(self):
        return np.any(self.target != 0, axis=0) | self._driving

    def _robot_loop(self):
        """The Pi's loop: the newest command that arrived goes to the Teensy; older ones are gone."""
        new = self._inbox_new
        self.target[:, new] = self._inbox[:, new]
        self._last_command[new] = self.t
        self._inbox_new = np.zeros_like(new)
        self._update_brake_at()

    def _communication_check(self):
        """communicationCheck(500): a robot without a command for brake_timeout brakes and forgets it."""
        braked = (self.t - self._last_command > self._brake) & self._active()
        if braked.any():
            self.target[:, braked] = 0.0
            self._stop(braked)
            self.brakes += int(np.count_nonzero(braked))
        self._update_brake_at()

    def _update_brake_at(self):
        active = self._active()
        self._brake_at = (max(self.t + 1, int(self._last_command[active].min()) + self._brake + 1)
                          if active.any() else np.inf)

    def _stop(self, robots):
        self.pwm[:, robots] = 0.0
        self.pwm_applied[:, robots] = 0.0
        self._driving[robots] = False
        if self.params.ideal_wheels:
            self.wheel_speed[:, robots] = 0.0

    def _pid(self):
        """The Teensy's 100 Hz interrupt: followCommands() -> noMotion() or PIDMotorControl()."""
        p = self.params
        v, w = self.target
        still = (np.abs(v) < p.deadband_linear) & (np.abs(w) < p.deadband_angular)
        if np.any(still & self._driving):
            self._stop(still & self._driving)
        on = ~still
        if not on.any():
            return
        wanted = model.unicycle_to_wheels(self.target[:, on], self.wheel_radius, self.base_length)
        if p.ideal_wheels:
            self.wheel_speed[:, on] = wanted
            self._driving[on] = True
            return
        self.pwm_applied[:, on] = self.pwm[:, on]   # moveL/moveR(the PWM of the previous period)
        counts = np.floor(self._angle[:, on] * (p.encoder_counts / (2 * np.pi)))
        start = ~self._driving[on]
        before, integral, pwm = self._counts_before[:, on], self._integral[:, on], self.pwm[:, on]
        if start.any():   # the PI starts afresh after a stop
            before[:, start], integral[:, start], pwm[:, start] = counts[:, start], 0.0, 0.0
            self._driving[on] = True
        measured = 2 * np.pi * (counts - before) / (p.encoder_counts * self._pid_seconds)
        error = wanted - measured
        integral += error * self._pid_seconds
        new_pwm = pwm + np.trunc(p.pid_kp * error + p.pid_ki * integral)
        saturated = np.abs(new_pwm) > PWM_MAX
        integral[saturated] -= error[saturated] * self._pid_seconds   # no integration at saturation
        new_pwm = np.clip(new_pwm, -PWM_MAX, PWM_MAX)
        self.pwm[:, on] = np.clip(new_pwm, pwm - p.pwm_slew, pwm + p.pwm_slew)
        self._integral[:, on] = integral
        self._counts_before[:, on] = counts

    def _move(self, k):
        """Motors, wheels and bodies over the next k ticks, in which the PWM stays as it is: each
        tick the wheel speed lags towards the PWM's free speed, then the robot moves one Euler
        tick with the new speed (heading wrapped when read)."""
        length = len(self._history)
        last = min(k, length)   # only the newest ticks stay in the history
        rows = (self.t + k - last + 1 + np.arange(last)) % length
        if not (self._driving.any() or self.wheel_speed.any()):
            self._history[rows] = self.true_poses
            return
        j = np.arange(1, k + 1)[:, None, None]
        if self.params.ideal_wheels:
            speeds = np.broadcast_to(self.wheel_speed, (k,) + self.wheel_speed.shape)
        else:
            free = self.pwm_applied * (self.params.motor_free_speed / PWM_MAX)
            speeds = free + (self.wheel_speed - free) * self._decay ** j
        self._angle += speeds.sum(axis=0) * TICK
        self.wheel_speed = speeds[-1].copy()
        left, right = self.radii[0] * speeds[:, 0], self.radii[1] * speeds[:, 1]      # k x N
        v, w = (left + right) * 0.5, (right - left) / self.base_length
        x0, y0, theta0 = self.true_poses
        theta = theta0 + np.cumsum(w, axis=0) * TICK                                   # after each tick
        before = np.vstack((theta0[None], theta[:-1]))                                 # heading during each tick
        x = x0 + np.cumsum(np.cos(before) * v, axis=0) * TICK
        y = y0 + np.cumsum(np.sin(before) * v, axis=0) * TICK
        self.true_poses = np.array([x[-1], y[-1], theta[-1]])
        self._history[rows] = np.stack((x[-last:], y[-last:], theta[-last:]), axis=1)

    def advance(self, n_ticks):
        """Run the pipeline's clock n_ticks ticks."""
        end = self.t + n_ticks
        while self.t < end:
            t = self.t
            if t >= self._next_arrival:
                self._deliver()
            if (t - self.loop_phase) % self._loop_ticks == 0 and self._inbox_new.any():
                self._robot_loop()
            if t >= self._brake_at:
                self._communication_check()
            pid_tick = (t - self.pid_phase) % self._pid_ticks == 0
            if pid_tick:
                self._pid()
            # the next tick at which something may happen
            after = t + 1
            nxt = min(end, after + (self.pid_phase - after) % self._pid_ticks, self._next_arrival, self._brake_at)
            if self._inbox_new.any():
                nxt = min(nxt, after + (self.loop_phase - after) % self._loop_ticks)
            self._move(int(nxt) - t)
            self.t = int(nxt)
        self.true_poses[2] = model.wrap_angle(self.true_poses[2])

    # -- the tracking system -----------------------------------------------------------------------

    def measured(self):
        """The poses the tracking system publishes now: tracking_latency old, with noise."""
        p = self.params
        poses = self._history[(self.t + 1) % len(self._history)].copy()
        n = self.number_of_robots
        if p.tracking_noise_position:
            poses[:2] += self.rng.normal(0.0, p.tracking_noise_position, (2, n))
        if p.tracking_noise_heading:
            poses[2] += self.rng.normal(0.0, p.tracking_noise_heading, n)
        poses[2] = model.wrap_angle(poses[2])
        return poses


def draw_seed():
    """A seed for an experiment that asked for none (reported, so the run can be repeated)."""
    return secrets.randbelow(2**31 - 1) + 1


class HardwareTestbed(model.Testbed):
    """The testbed in hardware-like mode: the debug report's counters and the commands in force
    exactly as model.Testbed keeps them (judged on the poses the tracker publishes, as the real
    Robotarium can only judge those), the motion through the Pipeline."""

    def __init__(self, initial_poses, config=DEFAULT, seed=None):
        super().__init__(initial_poses, config)
        self.seed = int(seed) if seed else draw_seed()
        self.pipeline = Pipeline(self.poses, HardwareParameters.from_config(config), self.seed,
                                 config.wheel_radius, config.base_length)
        self._step_ticks = ticks(config.time_step)
        self.latency = self.pipeline.params.latency

    def set_commands(self, ids, v, w, now=0.0, requested_exceeds_limits=False, offset=0.0, refreshed=False):
        super().set_commands(ids, v, w, now, requested_exceeds_limits, offset, refreshed)
        # Thresholded to the wheel limits as the ideal testbed does before its step.
        dxu = model.threshold_keeping_arc(np.vstack((np.asarray(v, dtype=float), np.asarray(w, dtype=float))),
                                          **self.limits)
        self.pipeline.send(ids, dxu[0], dxu[1], offset)

    def expire_commands(self, now, timeout=model.COMMAND_TIMEOUT):
        """As the ideal testbed, and the expired robots are sent a stop (the safety node re-sends the
        commands in force each tick, so the robots' own brake timer would run from the last of those)."""
        stale = super().expire_commands(now, timeout)
        if np.any(stale):
            ids = np.flatnonzero(stale)
            self.pipeline.send(ids, np.zeros(len(ids)), np.zeros(len(ids)))
        return stale

    def _move(self):
        self.pipeline.advance(self._step_ticks)
        self.poses = self.pipeline.measured()
