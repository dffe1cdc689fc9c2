"""The GTernal's sensors as the Robotarium simulator 2.x models them: plain numpy, no ROS.

Source of the models and numbers: the Robotarium Python simulator 2.1.0 (MIT licence;
rps/robotarium_abc.py, rps/robotarium.py, rps/utilities/sensors.py), written anew here and
vectorised; the numbers are in the testbed configuration (robotarium_core/testbed.yaml).
Distance sensors (7 rays per robot, stopped by obstacles, robots and, if set, the arena's edges;
dropouts, outliers, noise), wheel encoders and the IMU (accelerometer, gyroscope, magnetometer,
fused yaw), each drawn from the testbed's generator seeded per experiment.

The models, and where they differ from 2.1.0 on purpose: docs/rps2.md#the-sensor-models.
"""
import numpy as np

from robotarium_core.kinematics import points_ahead
from robotarium_core.model import unicycle_to_wheels

NUMBER_OF_DISTANCE_SENSORS = 7
GRAVITY = 9.81


def arena_walls(arena):
    """The arena's four edges as M x 2 x 2 segments ([start, end] of [x, y])."""
    x0, x1, y0, y1 = arena
    return np.array([[[x0, y0], [x1, y0]], [[x1, y0], [x1, y1]], [[x1, y1], [x0, y1]], [[x0, y1], [x0, y0]]],
                    dtype=float)


def sensor_rays(poses, sensor_poses, origin_offset):
    """Origins (2 x S x N) and unit directions (2 x S x N) of every robot's sensors."""
    theta = poses[2]
    c, s = np.cos(theta), np.sin(theta)
    frame_x = poses[0] + origin_offset * c
    frame_y = poses[1] + origin_offset * s
    sx, sy, heading = sensor_poses[0][:, None], sensor_poses[1][:, None], sensor_poses[2][:, None]
    origins = np.stack([frame_x + c * sx - s * sy, frame_y + s * sx + c * sy])
    angle = theta + heading
    return origins, np.stack([np.cos(angle), np.sin(angle)])


def true_distances(poses, segments, sensor_poses, origin_offset, robot_diameter, sensor_range):
    """Noise-free distance of every ray (S x N) to the nearest segment or other robot, `sensor_range`
    where nothing is nearer. segments: M x 2 x 2 (may be empty)."""
    origins, directions = sensor_rays(poses, sensor_poses, origin_offset)
    nearest = np.full(origins.shape[1:], float(sensor_range))
    ox, oy = origins
    dx, dy = directions * sensor_range                       # the whole ray, as 2.x parametrises it
    for (ax, ay), (bx, by) in np.asarray(segments, dtype=float).reshape(-1, 2, 2):
        ex, ey = bx - ax, by - ay
        denominator = dx * ey - dy * ex
        parallel = np.abs(denominator) < 1e-10
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((ax - ox) * ey - (ay - oy) * ex) / denominator  # along the ray, 0..1
            u = ((ax - ox) * dy - (ay - oy) * dx) / denominator  # along the segment, 0..1
        hit = ~parallel & (t >= 0) & (t <= 1) & (u >= 0) & (u <= 1)
        nearest = np.where(hit, np.minimum(nearest, t * sensor_range), nearest)

    n = poses.shape[1]
    if n > 1:
        radius = robot_diameter / 2
        centres = points_ahead(poses, origin_offset)   # 2 x N
        ux, uy = directions
        # to[k, s, i]: from ray (s, i)'s origin to robot k's disc centre
        tx = centres[0][:, None, None] - ox[None]
        ty = centres[1][:, None, None] - oy[None]
        along = tx * ux[None] + ty * uy[None]
        across2 = tx * tx + ty * ty - along * along
        half_chord = np.sqrt(np.maximum(radius * radius - across2, 0.0))
        entry = along - half_chord
        hit = (along >= 0) & (along <= sensor_range) & (across2 <= radius * radius) & (entry >= 0)
        hit &= np.arange(n)[:, None, None] != np.arange(n)[None, None, :]   # not one's own body
        candidate = np.where(hit, entry, np.inf).min(axis=0)
        nearest = np.minimum(nearest, candidate)
    return nearest


def noisy_distances(true, sensor_range, error, dropout_prob, outlier_prob, rng):
    """2.x's mixture: -1 where nothing is in range or the hit drops out, a uniform outlier, or the
    distance with Gaussian noise proportional to it, clipped to [0, range]."""
    readings = np.full(true.shape, -1.0)
    hit = true < sensor_range
    k = int(np.count_nonzero(hit))
    if k:
        d = true[hit]
        dropout = rng.random(k) < dropout_prob
        outlier = ~dropout & (rng.random(k) < outlier_prob)
        value = np.clip(d + error * d * rng.standard_normal(k), 0.0, sensor_range)
        value[outlier] = rng.uniform(0.0, sensor_range, int(np.count_nonzero(outlier)))
        value[dropout] = -1.0
        readings[hit] = value
    return readings


def endpoints(poses, distances, sensor_poses, origin_offset):
    """2 x S x N points each reading lands on (NaN where it reads -1), from the ray's own origin."""
    origins, directions = sensor_rays(poses, sensor_poses, origin_offset)
    d = np.where(distances >= 0, distances, np.nan)
    return origins + d[None] * directions


class SensorModel:
    """Every robot's sensors of one experiment: call `step` after each testbed step.

    config: a TestbedConfig; rng: a numpy Generator (the testbed seeds it per experiment);
    segments: the experiment's obstacles (M x 2 x 2), to which the arena's edges are added when the
    configuration says the sensors see them; distance_sensors: whether to compute the distance
    sensors (2.x: use_distance_sensors; otherwise they read NaN, as in 2.x).
    """

    def __init__(self, config, number_of_robots, rng, segments=(), distance_sensors=True):
        self.config = config
        self.rng = rng
        self.n = number_of_robots
        segments = np.asarray(segments, dtype=float).reshape(-1, 2, 2)
        if config.distance_sensors_see_walls:
            segments = np.concatenate([segments, arena_walls(config.arena)])
        self.segments = segments
        self.sensor_poses = config.distance_sensor_poses
        self.distance_sensors = distance_sensors
        # What 2.x reports before its first step: NaN distances, zeros elsewhere.
        s = NUMBER_OF_DISTANCE_SENSORS
        self.distances = np.full((s, number_of_robots), np.nan)
        self.distance_endpoints = np.full((2, s, number_of_robots), np.nan)
        self.accelerations = np.zeros((3, number_of_robots))
        self.gyros = np.zeros((3, number_of_robots))
        self.magnetic_fields = np.zeros((3, number_of_robots))
        self.orientations = np.zeros(number_of_robots)
        self._counts = np.zeros((2, number_of_robots))      # cumulative encoder counts (float, as 2.x)
        self._zero = np.zeros((2, number_of_robots))        # counts at the experiment's start
        self._previous = np.zeros((2, number_of_robots))    # the command applied in the previous step

    @property
    def encoders(self):
        """2 x N int32 counts (left, right) since the experiment's start."""
        return np.int32(self._counts) - np.int32(self._zero)

    def zero_encoders(self):
        """The experiment proper starts now (after the drive-on phase)."""
        self._zero = self._counts.copy()

    def step(self, poses, applied):
        """Readings after a step: poses are the new poses (3 x N), applied the (v, omega) the robots
        moved with in that step (2 x N, after thresholding)."""
        c, rng, n = self.config, self.rng, self.n
        dt = c.time_step
        if self.distance_sensors:
            true = true_distances(poses, self.segments, self.sensor_poses, c.distance_sensor_origin_offset,
                                  c.robot_diameter, c.distance_sensor_range)
            self.distances = noisy_distances(true, c.distance_sensor_range, c.distance_sensor_error,
                                             c.distance_sensor_dropout_prob, c.distance_sensor_outlier_prob, rng)
            self.distance_endpoints = endpoints(poses, self.distances, self.sensor_poses,
                                                c.distance_sensor_origin_offset)

        wheels = unicycle_to_wheels(applied, c.wheel_radius, c.base_length)              # rad/s
        delta = wheels * dt * c.encoder_counts_per_revolution * c.motor_gear_ratio / (2 * np.pi)
        delta = delta + c.encoder_noise_std * np.sqrt(np.maximum(np.abs(delta), 1.0)) * rng.standard_normal((2, n))
        self._counts += np.round(delta)

        v, w = applied
        linear = (v - self._previous[0]) / dt
        angular = (w - self._previous[1]) / dt
        imu_x, imu_y = c.imu_position
        zeros = np.zeros(n)
        true_acc = np.stack([linear - angular * imu_y - w * w * imu_x,
                             angular * imu_x - w * w * imu_y,
                             np.full(n, -GRAVITY)])
        self.accelerations = true_acc + np.asarray(c.accelerometer_noise_std)[:, None] * rng.standard_normal((3, n))
        self.gyros = np.stack([zeros, zeros, w]) + np.asarray(c.gyro_noise_std)[:, None] * rng.standard_normal((3, n))
        theta = poses[2]
        field = np.stack([c.magnetometer_xy_field * np.cos(theta), -c.magnetometer_xy_field * np.sin(theta),
                          np.full(n, c.magnetometer_z_field)])
        self.magnetic_fields = field + np.asarray(c.magnetometer_noise_std)[:, None] * rng.standard_normal((3, n))
        self.orientations = np.mod(np.degrees(theta) + c.orientation_noise_std * rng.standard_normal(n), 360.0)
        self._previous = np.array(applied, dtype=float)
