"""The Robotarium of the Robotarium Python simulator 2.x (2.1.0, MIT licence), on the ROS 2 testbed.

A subclass of the guide's Robotarium (robotarium.Robotarium, the DDS backend) that adds what 2.x
scripts use, with 2.x's names, defaults and shapes: the keyword-only constructor (obstacles,
distance sensors, skip_initialization, the show_* switches), the class constants from the
testbed's configuration, the sensor getters (the simulator computes the readings:
robotarium_core.sensors, on <ns>/sensors), debug() with 2.x's report, and the drive-on phase
(initialize: robotarium_core.rps2.DriveOn, 2.x's own algorithm, run in the script's process as 2.x
runs it, through the always-on safety node). What runs and where it differs: docs/rps2.md.
"""
import numpy as np

from robotarium_client import robotarium as backend
from robotarium_client import testbed_link
from robotarium_client.figure import live_figure
from robotarium_client.figure2 import ArenaFigure2
from robotarium_core import rps2
from robotarium_core.config import DEFAULT
from robotarium_core.model import RobotariumError
from robotarium_core.topics import SENSORS, TESTBED_QOS
from robotarium_msgs.msg import SensorReadings

KEYWORDS = {
    "number_of_robots": -1, "show_figure": False, "initial_conditions": np.array([]), "use_distance_sensors": False,
    "obstacles": None, "sim_in_real_time": True, "skip_initialization": False, "show_arena_boundaries": True,
    "show_robot_patches": True, "show_distance_endpoints": True, "show_distance_rays": False, "show_obstacles": True,
}
# 2.x's drive-on controller (rps/robotarium.py initialize()).
DRIVE_ON_CONTROLLER = dict(angular_velocity_limit=np.pi / 3.0, position_epsilon=0.03, position_error=0.05,
                           rotation_error=0.1)
SENSOR_HISTORY = 200           # readings kept (by run and step) while waiting for their poses


def constants(config):
    """2.x's class constants from a testbed configuration."""
    c = config
    return dict(
        TIME_STEP=c.time_step, MAX_LINEAR_VELOCITY=c.max_linear_velocity, ROBOT_DIAMETER=c.robot_diameter,
        WHEEL_RADIUS=c.wheel_radius, BASE_LENGTH=c.base_length, COLLISION_DIAMETER=c.collision_diameter,
        COLLISION_OFFSET=c.collision_offset, BOUNDARIES=np.array(c.arena), CENTER_OFFSET=c.distance_sensor_origin_offset,
        DISTANCE_SENSOR_ERROR=c.distance_sensor_error, DISTANCE_SENSOR_DROPOUT_PROB=c.distance_sensor_dropout_prob,
        DISTANCE_SENSOR_OUTLIER_PROB=c.distance_sensor_outlier_prob, DISTANCE_SENSOR_RANGE=c.distance_sensor_range,
        DISTANCE_SENSORS_ORIENTATION=c.distance_sensor_poses,
        ENCODER_COUNTS_PER_REVOLUTION=c.encoder_counts_per_revolution, MOTOR_GEAR_RATIO=c.motor_gear_ratio,
        IMU_ORIENTATION=np.array([*c.imu_position, 0.0]), ENCODER_NOISE_STD=c.encoder_noise_std,
        ACCELEROMETER_NOISE_STDS=np.array(c.accelerometer_noise_std), GYRO_NOISE_STDS=np.array(c.gyro_noise_std),
        MAGNETOMETER_NOISE_STDS=np.array(c.magnetometer_noise_std), MAGNETOMETER_Z_AVG=c.magnetometer_z_field,
        MAGNETOMETER_XY_AVG=c.magnetometer_xy_field, ORIENTATION_NOISE_STD=c.orientation_noise_std,
        MAX_WHEEL_VELOCITY=c.max_wheel_velocity, MAX_ANGULAR_VELOCITY=c.max_angular_velocity)


class Robotarium(backend.Robotarium):
    """rps.robotarium.Robotarium of the Robotarium simulator 2.x."""

    API = rps2.API   # "2", as api_level names it: its start request's api and its run record's

    def __init__(self, **kwargs):
        unknown = sorted(set(kwargs) - set(KEYWORDS))
        if unknown:
            raise TypeError("Robotarium() got unknown keyword argument(s) %s; the 2.x Robotarium takes %s."
                            % (", ".join(unknown), ", ".join(KEYWORDS)))
        a = dict(KEYWORDS, **kwargs)
        # 2.x's type checks, with its messages.
        for name, kind, what in (("number_of_robots", int, "NumberOfRobots"), ("show_figure", bool, "ShowFigure"),
                                 ("sim_in_real_time", bool, "SimInRealTime"),
                                 ("use_distance_sensors", bool, "UseDistanceSensors"),
                                 ("initial_conditions", np.ndarray, "InitialConditions")):
            value = a[name]
            if not isinstance(value, kind) or (kind is int and isinstance(value, bool)):
                raise RobotariumError("%s must be %s. Received type %s." % (
                    what, {int: "an integer", bool: "a boolean", np.ndarray: "a numpy ndarray"}[kind],
                    type(value).__name__))
        self.obstacles = rps2.check_obstacles(a["obstacles"])
        self._use_distance_sensors = a["use_distance_sensors"]
        self._skip_initialization = bool(a["skip_initialization"])
        self.show_arena_boundaries = a["show_arena_boundaries"]
        self.show_robot_patches = a["show_robot_patches"]
        self.show_distance_endpoints = a["show_distance_endpoints"]
        self.show_distance_rays = a["show_distance_rays"]
        self.show_obstacles = a["show_obstacles"]
        self.initializing = True
        self._readings_by_step = {}
        self._readings = None
        super().__init__(a["number_of_robots"], a["show_figure"], a["sim_in_real_time"], a["initial_conditions"])
        if not self._skip_initialization:
            self.initialize(self.initial_conditions)
        self.initializing = False

    # -- the 2.x API -------------------------------------------------------------------------------

    def debug(self):
        """End the experiment and print 2.x's report (and where the run was recorded)."""
        self.call_at_scripts_end()

    def get_distances(self):
        """7 x N distance readings in metres (-1: nothing within range or a dropout; NaN without
        use_distance_sensors)."""
        return self._reading("distances", (7, self.number_of_robots))

    def get_distance_endpoints(self):
        """2 x 7 x N points in the arena where each distance reading lands (NaN where it reads -1)."""
        return self._reading("distance_endpoints", (2, 7, self.number_of_robots))

    def get_encoders(self):
        """2 x N int32 wheel encoder counts (left, right) since the experiment started."""
        return self._reading("encoders", (2, self.number_of_robots), np.int32)

    def get_accelerations(self):
        """3 x N accelerometer readings in m/s^2 (x ahead, y left, z up; -9.81 on z at rest, as 2.x)."""
        return self._reading("accelerations", (3, self.number_of_robots))

    def get_gyros(self):
        """3 x N gyroscope readings in rad/s."""
        return self._reading("gyros", (3, self.number_of_robots))

    def get_magnetic_fields(self):
        """3 x N magnetometer readings in microtesla."""
        return self._reading("magnetic_fields", (3, self.number_of_robots))

    def get_orientations(self):
        """N fused yaw readings in degrees, in [0, 360)."""
        return self._reading("orientations", (self.number_of_robots,))

    def robot_colormap(self):
        import matplotlib.pyplot as plt  # matplotlib only for a script that draws
        return plt.get_cmap("tab20")

    # -- the drive-on phase ---------------------------------------------------------------------------

    def initialize(self, initial_conditions):
        """Drive from the charger slots to the initial conditions (2.x's algorithm, rps2.DriveOn; see
        the module)."""
        # rps, not at import: the script's first import of rps sets it up for one API (api_level)
        from rps.utilities.barrier_certificates import create_uni_barrier_certificate
        from rps.utilities.controllers import create_pose_controller_hybrid
        n = self.number_of_robots
        print("Initializing %d robots to initial conditions..." % n)
        label = None
        if self.show_figure:
            label = self._axes_handle.text(0, -0.5, "...INITIALIZING...", fontsize=20, color="b",
                                           fontweight="bold", ha="center", va="center", zorder=999)
        radius = rps2.drive_on_si_radius(initial_conditions, self.config)
        drive_on = rps2.DriveOn(initial_conditions, self.config, create_pose_controller_hybrid(**DRIVE_ON_CONTROLLER),
                                create_uni_barrier_certificate(safety_radius=radius - 0.1, projection_distance=0.05),
                                np.random)
        drive_on.run(self.get_poses, lambda dxu: self.set_velocities(np.arange(n), dxu), self.step)
        print("At initial conditions... Starting Experiment")
        if label is not None:
            label.remove()

    # -- hooks of the backend ---------------------------------------------------------------------------

    def _use_config(self, config):
        super()._use_config(config)
        self.__dict__.update(constants(config))

    def _default_initial_conditions(self):
        return rps2.random_poses(self.number_of_robots, np.random, self.config)

    def _complete_start_request(self, request):
        request.api = self.API
        request.obstacles = rps2.flatten_obstacles(self.obstacles)
        request.use_distance_sensors = self._use_distance_sensors
        request.sensor_seed = int(np.random.randint(1, 2 ** 31))   # 2.x's noise comes from the script's numpy
        if not self._skip_initialization:
            start = rps2.charger_slots(self.number_of_robots, np.random, self.config, goals=self.initial_conditions)
            request.drive_on_x, request.drive_on_y, request.drive_on_theta = request.x, request.y, request.theta
            request.x, request.y, request.theta = (row.tolist() for row in start)

    def _connect(self):
        super()._connect()
        self._link.node.create_subscription(SensorReadings, SENSORS, self._on_sensors, TESTBED_QOS)

    def _on_sensors(self, msg):
        self._readings_by_step[(msg.run_id, msg.step)] = msg
        while len(self._readings_by_step) > SENSOR_HISTORY:
            self._readings_by_step.pop(next(iter(self._readings_by_step)))

    _extra_velocity_rows_ignored = False   # 2.1.0 refuses a (3, N) velocity array (numpy's broadcast error)

    def get_poses(self):
        """2.x returns a copy of the poses (2.1.0 robotarium.py), not the live array 1.x hands out."""
        return super().get_poses().copy()

    def _advance(self, velocities):
        poses = super()._advance(velocities)
        self._readings = None
        return poses

    def _reading(self, field, shape, dtype=float):
        if self._readings is None:
            key = (self._link.run_id, self._last_step)
            if not self._link.spin_until(lambda: key in self._readings_by_step, testbed_link.STEP_TIMEOUT):
                raise RuntimeError("The testbed sent no sensor readings for step %d within %.0f s."
                                   % (self._last_step, testbed_link.STEP_TIMEOUT))
            self._readings = self._readings_by_step[key]
        return np.array(getattr(self._readings, field), dtype=dtype).reshape(shape)

    def _make_figure(self):
        super()._make_figure()
        if self._arena_figure is not None:
            self._fig, self._axes_handle = self.figure, self.axes

    def _new_arena_figure(self):
        """The live figure in 2.x's layout (robotarium_abc's _make_figure watches what is drawn on it)."""
        arena_figure = live_figure(self.config.arena, self.robot_radius, self.poses, ArenaFigure2)
        arena_figure.dress(self)
        return arena_figure


# 2.x's class constants (Robotarium.TIME_STEP, Robotarium.BOUNDARIES, ...), from the packaged
# configuration; an instance carries the testbed's own (_use_config).
for _name, _value in constants(DEFAULT).items():
    setattr(Robotarium, _name, _value)
