"""The one testbed configuration: a typed object loaded from a single YAML file. Plain Python.

Every default lives once, in `testbed.yaml` beside this module (a ROS 2 parameters file, so the
nodes take it with --params-file as it is). This module says what each value means and what a
valid one is; `TestbedConfig.load()` reads a file, `DEFAULT` is the packaged one. The simulator
publishes the configuration of a run when it starts (`to_yaml`), the recorder keeps it in the bag,
and the report is recomputed with it (`from_yaml`), so a run made with an edited file gets a report
made with the same numbers.
"""
import dataclasses
import math
import os
from collections.abc import Mapping
from typing import TYPE_CHECKING, Self

import yaml

if TYPE_CHECKING:
    import numpy as np

# libyaml's safe loader where PyYAML has it: the packaged file in 0.9 ms instead of 11 (every process reads it)
SAFE_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
DEFAULT_FILE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "testbed.yaml")

SIMULATOR, SAFETY, CLIENT = "simulator", "safety", "client"


@dataclasses.dataclass(frozen=True)
class Field:
    """What one configuration value means, its unit and valid range, and which nodes read it."""
    description: str
    low: float = -math.inf
    high: float = math.inf
    low_open: bool = True     # low itself is not allowed (> low) unless False (>= low)
    used_by: tuple = (SIMULATOR, SAFETY)
    integer: bool = False
    length: int = 0           # > 0: a list of this many numbers, each in [low, high]
    boolean: bool = False     # true or false
    names: bool = False       # a list of names (Python module names)


# name -> Field; the order is the YAML file's.
FIELDS = {
    "arena": Field("arena [x_min, x_max, y_min, y_max] in metres; robots outside count as boundary violations"),
    "robot_diameter": Field("m; robot centres this close count as a collision", 0.0),
    "wheel_radius": Field("m, GTernal wheel radius", 0.0),
    "base_length": Field("m between the wheels", 0.0),
    "max_linear_velocity": Field("m/s, largest forward speed", 0.0),
    "max_angular_velocity": Field("rad/s, largest turn rate", 0.0),
    "max_wheel_velocity": Field("rad/s, largest wheel speed", 0.0),
    "max_robots": Field("robots the simulator accepts in one experiment", 1, 1000, low_open=False,
                        used_by=(SIMULATOR,), integer=True),
    "real_testbed_max_robots": Field("robots the real Robotarium deploys; the report says when a run uses more",
                                     1, 1000, low_open=False, used_by=(SIMULATOR,), integer=True),
    "time_step": Field("s of simulated time per step", 0.0, 1.0),
    "rate": Field("Hz of the real-time loop (one step per tick)", 0.0, 1000.0, used_by=(SIMULATOR,)),
    "command_timeout": Field("s; a robot whose last command is older stops until a new one arrives", 0.0,
                             used_by=(SIMULATOR, SAFETY)),
    "boundary_margin": Field("m each robot's centre keeps from the arena edge (beyond what a latency adds)", 0.0, 0.5,
                             low_open=False, used_by=(SAFETY,)),
    "collision_margin": Field("m beyond robot_diameter that the safety node keeps between robot centres", 0.0, 0.5,
                              used_by=(SAFETY,)),
    "barrier_rate": Field("fraction of its remaining gap a pair of robot centres (in squared distance) or a centre "
                          "and the arena's margin line may close in one step (the safety node's discrete-time "
                          "barrier)", 0.0, 1.0, used_by=(SAFETY,)),
    "pose_timeout": Field("s; commands filtered with poses older than this become a stop", 0.0, used_by=(SAFETY,)),
    "lockstep_wait": Field("s a lockstep command waits for the poses it was computed from", 0.0, used_by=(SAFETY,)),
    "intervention_tolerance": Field("m/s or rad/s; a safe command further than this from the requested one is "
                                    "a safety intervention", 0.0, 1.0, low_open=False),
    "command_queue_depth": Field("arrays each command input (cmd_requested, cmd_safe) keeps until its node takes them",
                                 1, 100000, low_open=False, integer=True),
    "held_commands_limit": Field("arrays the safety node holds until the simulator matched its cmd_safe writer", 1,
                                 100000, low_open=False, used_by=(SAFETY,), integer=True),
    "time_limit": Field("s of testbed time after which the client ends an experiment (0: no limit)", 0.0,
                        low_open=False, used_by=(CLIENT,)),
    "client_lease": Field("s; a client gone this long (killed, crashed, network lost) loses its experiment", 0.1, 60.0,
                          used_by=(SIMULATOR,)),
    "line_lease": Field("s; a client waiting in line for a busy testbed that stops asking this long leaves the line",
                        0.5, 60.0, used_by=(SIMULATOR,)),
    "node_lease": Field("s; a simulator, safety node or recorder gone this long is reported lost (the client confirms "
                        "a simulator's or safety node's loss for as long again)", 0.1, 60.0),
    "claim_wait": Field("s a simulator, safety node or recorder started by ros2 run/launch listens for an older one "
                        "of its kind in its domain and namespace before it offers anything (robotarium_core.claim)",
                        0.0, 10.0, low_open=False, used_by=("every node (packaged file)",)),
    "recorder_dedup_window": Field("samples per topic whose identity the recorder remembers, to record a sample "
                                   "that two of its readers hear once", 1, 10_000_000, low_open=False,
                                   used_by=("recorder",), integer=True),
    "results_min_free": Field("MB that must be free where a run's folder goes (results/, bags/) before "
                              "./robotarium run starts anything", 0.0, low_open=False, used_by=(CLIENT,)),
    "run_data_limit": Field("MB of the script's data files copied into a run folder; files beyond it are left "
                            "out and named (0: none copied)", 0.0, low_open=False, used_by=(CLIENT,)),
    "viewer_rate": Field("Hz at which the simulator publishes the markers topic for viewers (RViz, Foxglove), "
                         "while one subscribes", 0.0, 100.0, used_by=(SIMULATOR,)),
    "trail_length": Field("s of testbed time of each robot's trail in the viewers", 0.0, 600.0, low_open=False,
                          used_by=(SIMULATOR,)),
    # the hardware-like mode (robotarium_sim.hardware); see testbed.yaml for each value's source
    "hardware": Field("true: every experiment runs hardware-like (latency, noise, wheel dynamics)",
                      used_by=(SIMULATOR,), boolean=True),
    "tracking_latency": Field("s from the true pose to the published one (hardware-like mode)", 0.0, 1.0,
                              low_open=False, used_by=(SIMULATOR,)),
    "tracking_noise_position": Field("m, standard deviation of published x and y (hardware-like mode)", 0.0, 0.1,
                                     low_open=False, used_by=(SIMULATOR,)),
    "tracking_noise_heading": Field("rad, standard deviation of the published heading (hardware-like mode)", 0.0, 1.0,
                                    low_open=False, used_by=(SIMULATOR,)),
    "command_latency": Field("s from cmd_safe to the robot (hardware-like mode)", 0.0, 1.0, low_open=False,
                             used_by=(SIMULATOR,)),
    "command_jitter": Field("s, extra command latency drawn in [0, jitter] (hardware-like mode)", 0.0, 1.0,
                            low_open=False, used_by=(SIMULATOR,)),
    "robot_loop_period": Field("s, the robot's command loop, newest command wins (hardware-like mode)", 0.0, 1.0,
                               used_by=(SIMULATOR,)),
    "pid_period": Field("s, the wheel-speed PID loop (hardware-like mode)", 0.0, 1.0, used_by=(SIMULATOR,)),
    "pid_kp": Field("PWM units per rad/s of speed error, each PID period (hardware-like mode)", 0.0, 1000.0,
                    low_open=False, used_by=(SIMULATOR,)),
    "pid_ki": Field("PWM units per rad of integrated speed error, each PID period (hardware-like mode)", 0.0,
                    1000.0, low_open=False, used_by=(SIMULATOR,)),
    "pwm_slew": Field("PWM units (of +-255) the motor command may change per PID period (hardware-like mode)", 0,
                      510, used_by=(SIMULATOR,), integer=True),
    "encoder_counts": Field("encoder counts per wheel turn (hardware-like mode)", 1, 10**7, low_open=False,
                            used_by=(SIMULATOR,), integer=True),
    "motor_free_speed": Field("rad/s of the wheel at PWM 255 (hardware-like mode)", 0.0, used_by=(SIMULATOR,)),
    "motor_time_constant": Field("s, lag of wheel speed behind the PWM (hardware-like mode)", 0.0, 10.0,
                                 low_open=False, used_by=(SIMULATOR,)),
    "deadband_linear": Field("m/s below which (with omega below deadband_angular) the motors are off "
                             "(hardware-like mode)", 0.0, 1.0, low_open=False, used_by=(SIMULATOR,)),
    "deadband_angular": Field("rad/s, see deadband_linear (hardware-like mode)", 0.0, 10.0, low_open=False,
                              used_by=(SIMULATOR,)),
    "brake_timeout": Field("s without a new command before the robot brakes (hardware-like mode)", 0.0, 60.0,
                           used_by=(SIMULATOR,)),
    "wheel_radius_spread": Field("relative standard deviation of each wheel's radius: drift (hardware-like mode)",
                                 0.0, 0.2, low_open=False, used_by=(SIMULATOR,)),
    # -- the 2.x API (robotarium_core.rps2, robotarium_core.sensors) --
    "obstacle_clearance": Field("m the safety node keeps between a robot's collider and an obstacle", 0.0, 0.5,
                                low_open=False, used_by=(SAFETY,)),
    "collision_diameter": Field("m; 2.x scripts: robots whose colliders are this close are too close", 0.0),
    "collision_offset": Field("m ahead of the axle where the 2.x collider sits", 0.0, 0.1, low_open=False),
    "distance_sensor_range": Field("m; a distance sensor ray that hits nothing nearer reads -1", 0.0,
                                   used_by=(SIMULATOR,)),
    "distance_sensor_error": Field("distance noise, standard deviation as a fraction of the distance", 0.0, 1.0,
                                   low_open=False, used_by=(SIMULATOR,)),
    "distance_sensor_dropout_prob": Field("probability that a hit reads -1", 0.0, 1.0, low_open=False,
                                          used_by=(SIMULATOR,)),
    "distance_sensor_outlier_prob": Field("probability that a hit reads uniform in [0, range]", 0.0, 1.0,
                                          low_open=False, used_by=(SIMULATOR,)),
    "distance_sensor_x": Field("m, x of the 7 distance sensors in the robot frame", -0.5, 0.5, used_by=(SIMULATOR,),
                               length=7),
    "distance_sensor_y": Field("m, y of the 7 distance sensors in the robot frame", -0.5, 0.5, used_by=(SIMULATOR,),
                               length=7),
    "distance_sensor_heading": Field("rad, heading of the 7 distance sensors in the robot frame", -4.0, 4.0,
                                     used_by=(SIMULATOR,), length=7),
    "distance_sensor_origin_offset": Field("m ahead of the axle where the sensor frame and ray-cast robot discs sit",
                                           -0.1, 0.1, used_by=(SIMULATOR,)),
    "distance_sensors_see_walls": Field("distance sensor rays stop at the arena's edges", used_by=(SIMULATOR,),
                                        boolean=True),
    "encoder_counts_per_revolution": Field("encoder counts per motor revolution", 0.0, used_by=(SIMULATOR,)),
    "motor_gear_ratio": Field("motor revolutions per wheel revolution", 0.0, used_by=(SIMULATOR,)),
    "encoder_noise_std": Field("counts per sqrt(count) of one step's travel", 0.0, low_open=False,
                               used_by=(SIMULATOR,)),
    "imu_position": Field("m, x and y of the IMU in the robot frame", -0.5, 0.5, used_by=(SIMULATOR,), length=2),
    "accelerometer_noise_std": Field("m/s^2, x y z", 0.0, low_open=False, used_by=(SIMULATOR,), length=3),
    "gyro_noise_std": Field("rad/s, x y z", 0.0, low_open=False, used_by=(SIMULATOR,), length=3),
    "magnetometer_noise_std": Field("uT, x y z", 0.0, low_open=False, used_by=(SIMULATOR,), length=3),
    "magnetometer_xy_field": Field("uT, horizontal magnetic field", used_by=(SIMULATOR,)),
    "magnetometer_z_field": Field("uT, vertical magnetic field", used_by=(SIMULATOR,)),
    "orientation_noise_std": Field("degrees, noise of the fused yaw", 0.0, low_open=False, used_by=(SIMULATOR,)),
    "sensor_seed": Field("seed of the sensors' noise where an experiment brings none", 0, 2**31 - 1,
                         low_open=False, used_by=(SIMULATOR,), integer=True),
    "standard_sensor_rate": Field("Hz of simulated time at which a 2.x experiment's sensors are also published per "
                                  "robot on standard message types (sensor_msgs Imu, MagneticField, Range); 0: off",
                                  0.0, 100.0, low_open=False, used_by=(SIMULATOR,)),
    "random_pose_spacing": Field("m between random 2.x initial conditions where N allows", 0.0, used_by=(CLIENT,)),
    "random_pose_min_spacing": Field("m; random 2.x initial conditions are never closer", 0.0, used_by=(CLIENT,)),
    "random_pose_area": Field("m, width and height of the box random 2.x initial conditions lie in", 0.0,
                              used_by=(CLIENT,), length=2),
    "safety_radius": Field("m; 2.x drive-on: points projection_distance ahead kept at least this plus "
                           "projection_distance apart", 0.0, used_by=(CLIENT,)),
    "projection_distance": Field("m ahead of the axle where the drive-on's barrier point sits", 0.0, used_by=(CLIENT,)),
    "charger_spacing": Field("m between the charger slots robots drive on from", 0.0, used_by=(CLIENT,)),
    "drive_on_wave_margin": Field("m; a robot waits on its charger until those going deeper are this much past its goal",
                                  0.0, used_by=(CLIENT,)),
    "drive_on_position_error": Field("m; the drive-on phase ends when every robot is this close to its pose", 0.0,
                                     used_by=(SIMULATOR, SAFETY, CLIENT)),
    "drive_on_rotation_error": Field("rad; ... and its heading this close", 0.0, used_by=(SIMULATOR, SAFETY, CLIENT)),
    "drive_on_max_steps": Field("steps before the drive-on phase gives up with an error", 1, 10**7,
                                low_open=False, used_by=(CLIENT,), integer=True),
    # -- ./robotarium verify --
    "verify_max_collision_iterations": Field("verify rejects a script with more collision iterations than this",
                                             0, 10**9, low_open=False, used_by=(CLIENT,), integer=True),
    "verify_max_boundary_iterations": Field("verify rejects a script with more iterations of robots outside the "
                                            "arena than this", 0, 10**9, low_open=False, used_by=(CLIENT,),
                                            integer=True),
    "verify_duration_factor": Field("verify rejects a script that runs longer than this times its declared "
                                    "duration", 0.0, 1000.0, used_by=(CLIENT,)),
    "verify_allowed_modules": Field("top-level modules a script may import under verify (stdlib: Python's "
                                    "standard library); its own modules beside it are allowed too",
                                    used_by=(CLIENT,), names=True),
}


class ConfigError(ValueError):
    """A configuration value that is missing, of the wrong kind or out of range."""


def _check(name: str, value: object) -> tuple[float, ...] | tuple[str, ...] | bool | int | float:
    field = FIELDS[name]
    if name == "arena":
        if (not isinstance(value, (list, tuple)) or len(value) != 4
                or not all(isinstance(v, (int, float)) and math.isfinite(v) for v in value)
                or not (value[0] < value[1] and value[2] < value[3])):
            raise ConfigError("%s must be [x_min, x_max, y_min, y_max] with min < max; received %r." % (name, value))
        return tuple(float(v) for v in value)
    if field.names:
        if (not isinstance(value, (list, tuple))
                or not all(isinstance(v, str) and v.replace("_", "a").isalnum() for v in value)):
            raise ConfigError("%s must be a list of module names (%s); received %r." % (name, field.description, value))
        return tuple(value)
    if field.boolean:
        if not isinstance(value, bool):
            raise ConfigError("%s must be true or false (%s); received %r." % (name, field.description, value))
        return value
    if field.length:
        if not isinstance(value, (list, tuple)) or len(value) != field.length:
            raise ConfigError("%s must be a list of %d numbers (%s); received %r."
                              % (name, field.length, field.description, value))
        return tuple(_check_number(name, field, v) for v in value)
    return _check_number(name, field, value)


def _check_number(name: str, field: Field, value: object) -> int | float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ConfigError("%s must be a finite number (%s); received %r." % (name, field.description, value))
    if field.integer and value != int(value):
        raise ConfigError("%s must be a whole number; received %r." % (name, value))
    low_ok = value > field.low if field.low_open else value >= field.low
    if not (low_ok and value <= field.high):
        raise ConfigError("%s must be in %s%g, %g]; received %r." % (
            name, "(" if field.low_open else "[", field.low, field.high, value))
    return int(value) if field.integer else float(value)


def _value_type(name: str, field: Field) -> type:
    """The type of a field's value once checked (_check)."""
    if name == "arena" or field.length or field.names:
        return tuple
    if field.boolean:
        return bool
    return int if field.integer else float


class _TestbedConfigBehaviour:
    """What a TestbedConfig does; its fields are FIELDS, in their order (TestbedConfig below is made
    from them, so the schema is written once: FIELDS, from which the nodes' parameter declarations and
    the checks of a file derive too)."""
    __test__ = False  # not a pytest class

    def __post_init__(self) -> None:
        for name in FIELDS:
            object.__setattr__(self, name, _check(name, getattr(self, name)))

    # -- derived values (never configured separately, so they cannot disagree) ---------------------

    @property
    def robot_radius(self) -> float:
        return self.robot_diameter / 2

    @property
    def boundaries(self) -> list[float]:
        """rps's [x_min, y_min, width, height]."""
        x_min, x_max, y_min, y_max = self.arena
        return [x_min, y_min, x_max - x_min, y_max - y_min]

    @property
    def distance_sensor_poses(self) -> "np.ndarray":
        """3 x 7: x, y and heading of each distance sensor in the robot frame (2.x
        DISTANCE_SENSORS_ORIENTATION)."""
        import numpy as np  # here only: the command line reads the configuration without numpy
        return np.array([self.distance_sensor_x, self.distance_sensor_y, self.distance_sensor_heading])

    @property
    def limits(self) -> dict[str, float]:
        """Keyword arguments of the model's thresholding and limit checks."""
        return dict(max_linear=self.max_linear_velocity, max_angular=self.max_angular_velocity,
                    max_wheel=self.max_wheel_velocity, wheel_radius=self.wheel_radius,
                    base_length=self.base_length)

    # -- reading and writing -------------------------------------------------------------------------

    @classmethod
    def from_dict(cls, values: Mapping[str, object], base: Self | None = None) -> Self:
        """A configuration from {name: value}; names not given are taken from `base` (or an error)."""
        unknown = sorted(set(values) - set(FIELDS))
        if unknown:
            raise ConfigError("unknown configuration values %s; known: %s." % (unknown, ", ".join(FIELDS)))
        merged = dataclasses.asdict(base) if base is not None else {}
        merged.update(values)
        missing = [name for name in FIELDS if name not in merged]
        if missing:
            raise ConfigError("the configuration lacks %s." % ", ".join(missing))
        return cls(**{name: merged[name] for name in FIELDS})

    @classmethod
    def load(cls, path: str | os.PathLike[str] = DEFAULT_FILE, base: Self | None = None) -> Self:
        """Read a ROS 2 parameters file (`/**: ros__parameters: {...}`) or a plain mapping."""
        with open(path) as f:
            document = yaml.load(f, Loader=SAFE_LOADER) or {}
        values = document
        if isinstance(document, dict) and len(document) == 1:
            (only,) = document.values()
            if isinstance(only, dict) and "ros__parameters" in only:
                values = only["ros__parameters"]
        if not isinstance(values, dict):
            raise ConfigError("%s holds no configuration mapping." % path)
        try:
            return cls.from_dict(values, base)
        except ConfigError as error:
            raise ConfigError("%s: %s" % (path, error)) from None

    def to_dict(self) -> dict[str, object]:
        return {name: list(value) if isinstance(value, tuple) else value
                for name, value in dataclasses.asdict(self).items()}

    def to_yaml(self) -> str:
        return yaml.safe_dump(self.to_dict(), sort_keys=False)

    @classmethod
    def from_yaml(cls, text: str, base: Self | None = None) -> Self:
        """The configuration a run published; values it lacks (an older run) come from `base`. Text that
        is not a YAML mapping (a foreign or damaged `config` message) raises ConfigError."""
        try:
            values = yaml.load(text, Loader=SAFE_LOADER) or {}
        except yaml.YAMLError as error:
            raise ConfigError("a run's configuration is not YAML: %s" % error) from None
        if not isinstance(values, dict):
            raise ConfigError("a run's configuration must be a mapping of names to values; received %r." % (values,))
        known = {k: v for k, v in values.items() if k in FIELDS}
        return cls.from_dict(known, base if base is not None else DEFAULT)


TestbedConfig = dataclasses.make_dataclass(
    "TestbedConfig", [(name, _value_type(name, field)) for name, field in FIELDS.items()],
    bases=(_TestbedConfigBehaviour,), frozen=True, module=__name__,
    namespace={"__doc__": "The testbed's numbers, one field per entry of FIELDS (see testbed.yaml for each one's "
                          "meaning and source): TestbedConfig.load(path), DEFAULT (the packaged file)."})


DEFAULT = TestbedConfig.load()
