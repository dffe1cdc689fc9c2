"""The testbed's side of the Robotarium simulator 2.x API: plain numpy, no ROS.

Scripts written against the Robotarium Python simulator 2.1.0 (MIT licence; read and written anew
here) are judged by its rules, which differ from the guide's (robotarium_core.model): colliders
ahead of the axle counted per pair and step, boundary steps, wheel-limit steps as a warning,
nothing counted during the drive-on phase; and beyond 2.x, a collider touching an obstacle counts
as an error. Also here: the drive-on phase (DriveOn), its charger slots and random initial
conditions, without 2.1.0's limits on the robot count. The rules and the differences:
docs/rps2.md.
"""
import numpy as np

from robotarium_core import kinematics, model
from robotarium_core.model import RobotariumError
from robotarium_core.sensors import SensorModel

API = "2"   # StartExperiment.api of a 2.x script's experiment


# -- obstacles ----------------------------------------------------------------------------------

def check_obstacles(obstacles, arena=model.ARENA):
    """An M x 2 x 2 float array of line segments ([[x1, y1], [x2, y2]] each) from what a script
    passed (None or empty: none), or a RobotariumError that says what is wrong."""
    if obstacles is None:
        return np.zeros((0, 2, 2))
    try:
        segments = np.array(obstacles, dtype=float)
    except (TypeError, ValueError):
        raise RobotariumError("obstacles must be an M x 2 x 2 numpy array of line segments [[x1, y1], [x2, y2]]; "
                              "received %r." % (obstacles,)) from None
    if segments.size == 0:
        return np.zeros((0, 2, 2))
    if segments.ndim != 3 or segments.shape[1:] != (2, 2):
        raise RobotariumError("obstacles must be an M x 2 x 2 array of line segments [[x1, y1], [x2, y2]]; received "
                              "an array of shape %s." % (segments.shape,))
    if not np.all(np.isfinite(segments)):
        raise RobotariumError("obstacles must be finite; obstacle(s) %s hold NaN or inf."
                              % np.flatnonzero(~np.all(np.isfinite(segments), axis=(1, 2))).tolist())
    return segments


def flatten_obstacles(segments):
    """M x 2 x 2 -> [x1, y1, x2, y2, ...] (StartExperiment.obstacles)."""
    return np.asarray(segments, dtype=float).reshape(-1).tolist()


def unflatten_obstacles(values):
    values = np.asarray(values, dtype=float)
    if values.size % 4:
        raise RobotariumError("obstacles must hold 4 numbers (x1, y1, x2, y2) per segment; received %d numbers."
                              % values.size)
    return check_obstacles(values.reshape(-1, 2, 2))


def point_segment_distances(points, segments):
    """N x M distances from points (2 x N) to segments (M x 2 x 2)."""
    p = np.asarray(points, dtype=float).T[:, None, :]            # N x 1 x 2
    a, b = segments[None, :, 0, :], segments[None, :, 1, :]      # 1 x M x 2
    ab = b - a
    length2 = np.einsum("...k,...k->...", ab, ab)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(length2 > 0, np.einsum("...k,...k->...", p - a, ab) / length2, 0.0)
    closest = a + np.clip(t, 0.0, 1.0)[..., None] * ab
    return np.linalg.norm(p - closest, axis=-1)


# -- validation as 2.x does it ----------------------------------------------------------------------

def colliders(poses, offset):
    """2 x N centres of the 2.x colliders, `offset` ahead of each axle."""
    return kinematics.points_ahead(poses, offset)


def count_too_close(poses, diameter, offset):
    """Pairs of robots whose colliders are within `diameter` (2.x counts each pair)."""
    c = colliders(poses, offset)
    i, j = model.robot_pairs(poses.shape[1])
    return int(np.count_nonzero(np.hypot(c[0, i] - c[0, j], c[1, i] - c[1, j]) <= diameter))


def count_obstacle_hits(poses, segments, diameter, offset):
    """Robots whose collider touches an obstacle segment."""
    if len(segments) == 0:
        return 0
    distances = point_segment_distances(colliders(poses, offset), segments)
    return int(np.count_nonzero(np.any(distances <= diameter / 2, axis=1)))


def exceeds_wheel_limit(dxu, config):
    """2.x's actuator check: some wheel of the command as set faster than the limit (no clipping)."""
    wheels = model.unicycle_to_wheels(dxu, config.wheel_radius, config.base_length)
    return bool(np.any(np.abs(wheels) > config.max_wheel_velocity))


def at_pose(poses, goals, position_error, rotation_error):
    """(all there, per robot mask) as 2.x's create_at_pose."""
    mask = model.at_pose_mask(poses, goals, position_error, rotation_error)
    return bool(np.all(mask)), mask


def debug_report(iterations, too_close, outside, actuator, time_step=model.TIME_STEP, completed=True, safety=None):
    """The text 2.x's Robotarium.debug() prints, character for character. A robot touching one of
    the script's obstacles is not judged: 2.x draws obstacles, for its distance sensors, and never
    checks them (report.txt gives the count). A run that did not complete gets no verdict that it
    will run: model.NOT_COMPLETED instead. Where the safety layer changed the script's commands
    (safety: model.safety_lines' keyword arguments) the robots drove something else than the
    Robotarium would have: the report says so instead of giving this run's duration, counts and
    verdict as the script's."""
    changed = model.safety_lines(**(safety or {}))
    if changed:
        return "".join(changed + ([] if completed else ["\n" + model.NOT_COMPLETED]))
    lines = ["Your simulation took approximately {0:.2f} real seconds to execute.\n\n".format(iterations * time_step)]
    hard = too_close + outside
    if hard == 0 and not completed:
        if actuator:
            lines.append("WARNING: {0} out of {1} (~{2:.0f}%) timesteps had velocity command(s) exceed actuator "
                         "limits.\n\n".format(actuator, iterations, 100 * actuator / max(iterations, 1)))
        lines.append(model.NOT_COMPLETED)
    elif hard == 0 and actuator == 0:
        lines.append("No errors or warnings in your simulation!  Your script will run on the Robotarium!\n\n")
    elif hard == 0:
        lines.append("No hard errors detected, your script will run on the Robotarium!\n\n")
        lines.append("WARNING: {0} out of {1} (~{2:.0f}%) timesteps had velocity command(s) exceed actuator limits.\n"
                     "         A large percentage of exceeded actuator commands will cause noticeable\n"
                     "         differences between this simulation and the physical Robotarium.\n"
                     .format(actuator, iterations, 100 * actuator / max(iterations, 1)))
    else:
        lines.append("Errors detected, your script will NOT run on the Robotarium!\n\n")
        lines.append("Errors:\n")
        if too_close:
            lines.append("\t Simulation had {0} time steps where robots were too close (potential collision).\n"
                         .format(too_close))
        if outside:
            lines.append("\t Simulation had {0} time steps where robots were outside boundaries.\n".format(outside))
        lines.append("\nPlease fix the noted errors in your simulation; otherwise, your experiment will be rejected.\n")
    return "".join(lines)


class Testbed2(model.Testbed):
    """model.Testbed judged by 2.x's rules, with obstacles, sensors and the drive-on phase.

    drive_on_goals: 3 x N poses the drive-on phase drives to (None: no drive-on phase). Nothing is
    counted while it lasts; it ends when the poses after a step are all at the goals (as 2.x's
    at_pose with the configured errors), and counting starts one step later: 2.x's loop sees those
    poses, steps once more, then starts the experiment.
    """

    def __init__(self, initial_poses, config=model.DEFAULT, obstacles=None, drive_on_goals=None,
                 distance_sensors=False, rng=None):
        super().__init__(initial_poses, config)
        self.obstacles = check_obstacles(obstacles, config.arena)
        self.obstacle_hits = 0
        self.drive_on_goals = None if drive_on_goals is None else np.array(drive_on_goals, dtype=float)
        self.drive_on_done_at = None if self.drive_on_goals is not None else -1   # step whose poses reached them
        self.applied = np.zeros((2, self.number_of_robots))
        rng = rng if rng is not None else np.random.default_rng(config.sensor_seed)
        self.sensors = SensorModel(config, self.number_of_robots, rng, self.obstacles, distance_sensors)

    @property
    def initializing(self):
        return self.drive_on_done_at is None or self.steps <= self.drive_on_done_at

    def step(self):
        counting = not self.initializing
        if counting and self.steps == self.drive_on_done_at + 1 and self.drive_on_goals is not None:
            self.sensors.zero_encoders()   # the experiment proper starts now
        before, commands = self.poses.copy(), self.velocities.copy()
        kept = (self.collisions, self.boundary_violations, self.actuator_limit_iterations)
        super().step()
        self.collisions, self.boundary_violations, self.actuator_limit_iterations = kept
        if counting:
            c = self.config
            self.collisions += count_too_close(before, c.collision_diameter, c.collision_offset)
            self.boundary_violations += int(np.any(model.outside_arena(before, c.arena)))
            if self.requested_exceeds_limits or exceeds_wheel_limit(commands, c):
                self.actuator_limit_iterations += 1
            self.obstacle_hits += count_obstacle_hits(before, self.obstacles, c.collision_diameter,
                                                      c.collision_offset)
        self.applied = model.threshold_keeping_arc(commands, **self.limits)
        self.sensors.step(self.poses, self.applied)
        if self.drive_on_done_at is None and at_pose(self.poses, self.drive_on_goals,
                                                     self.config.drive_on_position_error,
                                                     self.config.drive_on_rotation_error)[0]:
            self.drive_on_done_at = self.steps

    def report(self, completed=True, safety=None):
        return debug_report(self.steps, self.collisions, self.boundary_violations, self.actuator_limit_iterations,
                            self.time_step, completed, safety)


# -- where robots start ----------------------------------------------------------------------------------

def charger_slots(number_of_robots, rng, config=model.DEFAULT, goals=None):
    """3 x N poses on charger slots, facing into the arena: along the top and bottom edges (2.x: 11
    slots per edge, a robot radius from it), and along the left and right edges too when N needs
    more than those hold. Slots are `charger_spacing` apart, so no two robots start closer than the
    testbed's safety layer allows. With goals (3 x N, where the robots will drive), each robot gets
    the slot that makes the paths shortest in total (they seldom cross); without, slots are drawn at
    random, as 2.x draws them."""
    x_min, x_max, y_min, y_max = config.arena
    width = x_max - x_min - config.robot_diameter
    height = y_max - y_min - config.robot_diameter
    cx, cy = (x_min + x_max) / 2, (y_min + y_max) / 2
    spacing = config.charger_spacing
    xs = cx + np.linspace(-width / 2, width / 2, int(np.floor(width / spacing)) + 1)
    slots = [(x, cy - height / 2, np.pi / 2) for x in xs] + [(x, cy + height / 2, -np.pi / 2) for x in xs]
    if number_of_robots > len(slots):   # the sides, clear of the corner slots
        side = int(np.floor((height - 2 * spacing) / spacing)) + 1
        ys = cy + np.linspace(-height / 2 + spacing, height / 2 - spacing, side)
        slots += [(cx - width / 2, y, 0.0) for y in ys] + [(cx + width / 2, y, np.pi) for y in ys]
    if number_of_robots > len(slots):
        raise RobotariumError("%d robots do not fit on charger slots %.2f m apart around this arena."
                              % (number_of_robots, spacing))
    slots = np.array(slots, dtype=float)
    if goals is None:
        return slots[rng.choice(len(slots), number_of_robots, replace=False)].T
    from scipy.optimize import linear_sum_assignment  # here: slow to import, needed only with goals
    goals = np.asarray(goals, dtype=float)
    cost = np.hypot(goals[0][:, None] - slots[:, 0][None], goals[1][:, None] - slots[:, 1][None])
    robots, chosen = linear_sum_assignment(cost)
    return slots[chosen[np.argsort(robots)]].T


def depth_into_arena(poses, start):
    """How far each robot is in from its charger slot, along the direction the slot faces."""
    return (poses[0] - start[0]) * np.cos(start[2]) + (poses[1] - start[1]) * np.sin(start[2])


def drive_on_waiting(poses, start, goals, arrived, margin):
    """Which robots wait on their chargers: those whose goal is shallower than a robot still on its
    way to a deeper goal, until that robot has gone `margin` deeper than this goal (or arrived).
    Robots at their goals then never wall in the ones still to come, even in a crowd of 50."""
    goal_depth = depth_into_arena(goals, start)
    depth = depth_into_arena(poses, start)
    line = goal_depth[:, None] + margin   # row i: robot i's goal depth plus the margin
    ahead = ~arrived[None, :] & (goal_depth[None, :] > line)
    return np.any(ahead & (depth[None, :] < line), axis=1)


def spaced_random_positions(number, spacing, width, height, rng, attempts=10000):
    """2 x number positions uniform in a centred width x height box, at least `spacing` apart, by 2.x's
    rejection sampling (rps/utilities/misc.py): per attempt one candidate from rng.random(2), kept if
    far enough from those kept so far; None if not all are placed within `attempts` (2.x's budget)."""
    accepted = []
    for _ in range(attempts):
        candidate = (rng.random(2) - 0.5) * [width, height]
        if not accepted or np.all(np.linalg.norm(np.array(accepted) - candidate, axis=1) >= spacing):
            accepted.append(candidate)
            if len(accepted) == number:
                return np.array(accepted).T
    return None


def random_poses(number_of_robots, rng, config=model.DEFAULT):
    """3 x N random initial conditions as 2.x draws them (uniform in a centred box, at least
    `random_pose_spacing` apart, headings uniform), with the spacing lowered in steps of 5 cm down
    to `random_pose_min_spacing` where N robots do not fit, and, below that, random cells of a grid
    of that spacing. 2.1.0 always asks for 0.5 m, which 18 or more robots never fit."""
    width, height = config.random_pose_area
    spacing, floor = config.random_pose_spacing, config.random_pose_min_spacing
    while spacing >= floor - 1e-9:
        positions = None
        if number_of_robots <= int(np.floor(width * height / spacing ** 2)):
            positions = spaced_random_positions(number_of_robots, spacing, width, height, rng)
        if positions is not None:
            break
        spacing -= 0.05
    else:
        return _crowd_poses(number_of_robots, rng, config)
    x_min, x_max, y_min, y_max = config.arena
    centre = np.array([[(x_min + x_max) / 2], [(y_min + y_max) / 2]])
    return np.vstack([positions + centre, rng.random(number_of_robots) * 2 * np.pi - np.pi])


def _crowd_poses(number_of_robots, rng, config):
    """Random cells of a grid, for more robots than fit `random_pose_min_spacing` apart at random:
    the grid keeps that distance (less, down to 0.25 m, where N needs it) from the charger slots, so
    robots that have arrived never block those still driving on, and each heading is drawn until
    the points 5 cm ahead stay farther apart than the safety layer keeps them (0.17 m) plus 2 cm."""
    x_min, x_max, y_min, y_max = config.arena
    clear = config.random_pose_min_spacing
    width = x_max - x_min - config.robot_diameter - 2 * clear
    height = y_max - y_min - config.robot_diameter - 2 * clear
    spacing = clear
    while True:
        xs = np.linspace(-width / 2, width / 2, int(np.floor(width / spacing + 1e-9)) + 1)
        ys = np.linspace(-height / 2, height / 2, int(np.floor(height / spacing + 1e-9)) + 1)
        if len(xs) * len(ys) >= number_of_robots or spacing <= 0.25:
            break
        spacing -= 0.01
    cells = np.array([(x, y) for x in xs for y in ys]) + [(x_min + x_max) / 2, (y_min + y_max) / 2]
    if number_of_robots > len(cells):
        raise RobotariumError("%d robots do not fit %.2f m apart in the arena." % (number_of_robots, spacing))
    positions = cells[rng.choice(len(cells), number_of_robots, replace=False)]
    gap = config.safety_radius + config.projection_distance + 0.02
    ahead = np.full((number_of_robots, 2), np.inf)
    headings = np.zeros(number_of_robots)
    for i, p in enumerate(positions):
        for _ in range(1000):
            theta = rng.random() * 2 * np.pi - np.pi
            point = p + config.projection_distance * np.array([np.cos(theta), np.sin(theta)])
            if np.all(np.linalg.norm(ahead[:i] - point, axis=1) >= gap):
                break
        headings[i], ahead[i] = theta, point
    return np.vstack([positions.T, headings])


# -- the drive-on phase ------------------------------------------------------------------------------

DRIVE_ON_SI_RADIUS = 0.25   # m between points 5 cm ahead: 2.x's create_uni_barrier_certificate() default


def drive_on_si_radius(goals, config=model.DEFAULT):
    """The drive-on barrier's distance between points 5 cm ahead: 2.x's 0.25 m, less where the
    initial conditions themselves are closer (they must stay reachable); never less than the
    the guide's unicycle certificate keeps (safety_radius + projection_distance), or the goals could
    never be reached (an error that says so)."""
    n = goals.shape[1]
    if n < 2:
        return DRIVE_ON_SI_RADIUS
    ahead = colliders(goals, config.projection_distance)
    i, j = model.robot_pairs(n)
    gaps = np.hypot(ahead[0, i] - ahead[0, j], ahead[1, i] - ahead[1, j])
    k = int(np.argmin(gaps))
    kept = config.safety_radius + config.projection_distance
    if gaps[k] - 0.01 < kept:
        raise RobotariumError(
            "initial_conditions put the points %.0f cm ahead of robots %d and %d %.3f m apart; the drive-on phase's "
            "barrier keeps them at least %.2f m apart, so it could never bring them there. Space "
            "the initial conditions further apart, or pass skip_initialization=True."
            % (100 * config.projection_distance, i[k], j[k], gaps[k], kept))
    return min(DRIVE_ON_SI_RADIUS, gaps[k] - 0.01)


class DriveOn:
    """The drive-on phase (2.x's Robotarium.initialize, rps/robotarium.py), in plain numpy: robots
    drive from their charger slots to `goals` with 2.x's hybrid pose controller, through 2.x's
    unicycle barrier certificate, and a robot that makes no progress for DEADLOCK_STEPS takes a
    random detour (a waypoint within DETOUR of where it is stuck), as in 2.x.

    Beyond 2.x, so that a crowd of up to 50 robots settles (2.x's rules made robots 2-5 cm from
    their goals, blocked by a neighbour while finishing, take detours that pushed their neighbours
    off theirs, for ever): robots going deep leave their chargers first (drive_on_waiting); a robot
    within drive_on_position_error of its goal takes no detour and holds back no one; one that
    stays there without arriving for DEADLOCK_STEPS turns where it is instead of first closing
    the last 2 cm; and one pushed out of it approaches again.

    controller: 2.x's hybrid pose controller, f(states, poses, approach) -> (dxu, approach); barrier:
    2.x's unicycle certificate f(dxu, x); rng: where detours are drawn (2.x: numpy's global
    generator); waves: whether robots wait on their chargers (drive_on_waiting: the rule needs robots
    that start on the arena's edges facing in; a hardware arena's robots start wherever they stand).
    """
    DEADLOCK_STEPS = 5 * 30   # steps without DEADLOCK_DISTANCE of progress before a robot takes a detour
    DEADLOCK_DISTANCE = 0.1   # m
    DETOUR = 0.25             # m, how far a detour waypoint may lie from where the robot is stuck

    def __init__(self, goals, config, controller, barrier, rng=np.random, waves=True):
        self.waves = waves   # False: nobody waits (robots that start anywhere, not on chargers along the edges)
        self.goals, self.config = np.asarray(goals, dtype=float), config
        self.controller, self.barrier, self.rng = controller, barrier, rng
        self.number_of_robots = self.goals.shape[1]
        self.steps = 0

    def there(self, poses):
        """(all there, per robot mask): the drive-on phase's end, as the testbed judges it."""
        c = self.config
        return at_pose(poses, self.goals, c.drive_on_position_error, c.drive_on_rotation_error)

    def run(self, get_poses, set_velocities, step):
        """Drive on, through the caller's get_poses() -> 3 x N, set_velocities(2 x N) and step(),
        in 2.x's order (poses, step, then per loop: poses, commands, step; the loop ends on the
        poses it last read, so one step follows the poses at the goals). Returns the loop's steps;
        raises a RobotariumError naming the robots still away after drive_on_max_steps."""
        n, c, goals = self.number_of_robots, self.config, self.goals
        x = get_poses()
        start = x.copy()
        step()
        timers = np.zeros(n, dtype=int)
        last = x.copy()
        detouring = np.zeros(n, dtype=bool)
        detours = np.zeros((3, n))
        approach = np.ones(n)
        settling = np.zeros(n, dtype=int)   # steps near the goal, not there
        while not self.there(x)[0]:
            if self.steps >= c.drive_on_max_steps:
                away = np.flatnonzero(~self.there(x)[1]).tolist()
                raise RobotariumError("The drive-on phase did not bring robots %s to their initial conditions within "
                                      "%d steps; space the initial conditions further apart, or pass "
                                      "skip_initialization=True." % (away, self.steps))
            x = get_poses()
            arrived = self.there(x)[1]
            # A robot within the position error of its goal only has to turn: it takes no detours (they
            # would push its neighbours off their goals) and holds back no one (drive_on_waiting).
            near = np.hypot(*(x[:2] - goals[:2])) <= c.drive_on_position_error
            # Robots going deep leave first (drive_on_waiting): a crowd never walls itself in.
            waiting = (drive_on_waiting(x, start, goals, arrived | near, c.drive_on_wave_margin) if self.waves
                       else np.zeros(n, dtype=bool))
            timers[waiting | near] = self.steps
            detouring[near] = False
            last[:, near] = x[:, near]
            # The hybrid controller drives a robot to within 2 cm of its position before it turns; one
            # that cannot get there (a neighbour's barrier in the way) turns where it is, once it has
            # been near for DEADLOCK_STEPS. A robot pushed out of the position error approaches again
            # (the controller alone would leave one that faces its goal standing still).
            settling = np.where(near & ~arrived, settling + 1, 0)
            approach[~near] = 1.0
            approach[settling > self.DEADLOCK_STEPS] = 0.0
            dxu, approach = self.controller(x, goals, approach)
            # whether the controller still asks for more than 0.1 (2.x's "progress" probe); read here,
            # before any command is replaced: for every robot it is used on (not near: approach 1) it
            # is what a fresh call with approach 1 would say
            pulling = np.linalg.norm(dxu, axis=0) > 0.1
            dxu[:, waiting] = 0.0
            # 2.x's deadlock rule: a robot that has not moved DEADLOCK_DISTANCE for DEADLOCK_STEPS (while
            # its controller still asks for more than 0.1) drives to a random waypoint until it has.
            active = ~arrived & ~waiting & ~near
            moved = np.hypot(*(last[:2] - x[:2])) > self.DEADLOCK_DISTANCE
            idle = self.steps - timers > self.DEADLOCK_STEPS
            on = active & detouring
            if np.any(on):
                dxu[:, on] = self.controller(x[:, on], detours[:, on], np.ones(np.count_nonzero(on)))[0]
            new = active & ~detouring & idle & ~moved
            progress = active & ~detouring & ~new & (moved | ~pulling)
            detouring[on & moved] = False
            detouring[new] = True
            draw = new | (on & ~moved & idle)
            detours[:, draw] = self.detours(x[:, draw])
            timers[draw | progress] = self.steps
            last[:, progress] = x[:, progress]
            self.steps += 1
            set_velocities(self.barrier(dxu, x))
            step()
        return self.steps

    def detours(self, poses):
        """3 x K random waypoints, each within DETOUR of a stuck robot (poses 3 x K), inside the arena
        (2.x: a random pose +-0.25 m around it, from numpy's global generator)."""
        x_min, x_max, y_min, y_max = self.config.arena
        margin, k = self.config.robot_diameter, poses.shape[1]
        return np.vstack([np.clip(poses[0] + self.rng.uniform(-self.DETOUR, self.DETOUR, k), x_min + margin, x_max - margin),
                          np.clip(poses[1] + self.rng.uniform(-self.DETOUR, self.DETOUR, k), y_min + margin, y_max - margin),
                          self.rng.uniform(-np.pi, np.pi, k)])
