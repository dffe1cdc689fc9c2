"""robotarium fleet: a simulated fleet of robots that behave as separate machines, for ./robotarium up --fleet."""
HELP = "a simulated fleet: N robot processes and a motion-capture or camera stand-in (then: up --fleet FILE)"
DESCRIPTION = ("N robot processes (each its own ROS node: its cmd_vel, the GTernal's wheel model, its own command "
               "timeout) and a motion-capture stand-in (PoseStamped per robot, 120 Hz, noise, dropouts) or, with "
               "--tracking camera, a camera stand-in (30 Hz images with each robot's ArUco tag). It writes the fleet "
               "file it serves, prints one line per robot (robot r2 pid 12345), then 'fleet ready', and "
               "runs until Ctrl-C. Then ./robotarium up --fleet FILE moves these robots as a lab's own "
               "(docs/own-robots.md).")


def add_arguments(parser):
    from robotarium_hardware import sim_fleet
    sim_fleet.add_arguments(parser)


def main(args):
    from robotarium_hardware import sim_fleet
    return sim_fleet.run(args)
