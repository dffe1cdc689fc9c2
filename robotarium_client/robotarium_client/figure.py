"""The arena figure of the Robotarium class: the arena and every robot to scale, heading visible.

Drawn as rps draws it (a square chassis, two wheels, two LEDs at the front) so that the guide's
plotting examples, which draw on r.axes with scatter/text/plot/imshow, look as they do there.
With no display (or MPLBACKEND=Agg) the figure is built on the Agg backend and not redrawn
every step: nobody would see it, and a script's savefig() still renders it fully.
"""
import math
import os

import numpy as np


def _use_headless_backend_if_needed():
    import matplotlib
    if os.environ.get("MPLBACKEND"):
        return
    if not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
        matplotlib.use("Agg")


class ArenaFigure:
    def __init__(self, boundaries, robot_radius, poses):
        _use_headless_backend_if_needed()
        import matplotlib.patches as patches
        import matplotlib.pyplot as plt

        self.plt = plt
        self.robot_radius = robot_radius
        self.interactive = plt.get_backend().lower() not in ("agg", "pdf", "svg", "ps", "cairo", "template")
        self.figure, self.axes = plt.subplots()
        self.axes.set_axis_off()
        self.chassis, self.left_wheels, self.right_wheels, self.left_leds, self.right_leds = [], [], [], [], []
        for x, y, theta in poses.T:
            self.chassis.append(patches.RegularPolygon((x, y), 4, radius=math.sqrt(2) * robot_radius,
                                                       orientation=theta + math.pi / 4, facecolor="#FFD700",
                                                       edgecolor="k"))
            self.right_wheels.append(patches.Circle((x, y), 0.02, facecolor="k"))
            self.left_wheels.append(patches.Circle((x, y), 0.02, facecolor="k"))
            self.right_leds.append(patches.Circle((x, y), robot_radius / 5, fill=False))
            self.left_leds.append(patches.Circle((x, y), robot_radius / 5, fill=False))
        for group in (self.right_wheels, self.left_wheels, self.chassis, self.left_leds, self.right_leds):
            for patch in group:
                self.axes.add_patch(patch)
        self.axes.add_patch(patches.Rectangle(boundaries[:2], boundaries[2], boundaries[3], fill=False))
        self.axes.set_xlim(boundaries[0] - 0.1, boundaries[0] + boundaries[2] + 0.1)
        self.axes.set_ylim(boundaries[1] - 0.1, boundaries[1] + boundaries[3] + 0.1)
        self.axes.set_aspect("equal")
        self.place(poses)
        if self.interactive:
            plt.ion()
            plt.show()
        plt.subplots_adjust(left=-0.03, right=1.03, bottom=-0.03, top=1.03, wspace=0, hspace=0)

    def place(self, poses):
        """Move every patch to the robots' poses (the same offsets as rps)."""
        r = self.robot_radius
        for i, (x, y, theta) in enumerate(poses.T):
            c, s = math.cos(theta), math.sin(theta)
            centre = np.array((x, y))
            side = np.array((-s, c))          # unit vector to the robot's left
            self.chassis[i].xy = (x, y)
            self.chassis[i].orientation = theta + math.pi / 4
            self.left_wheels[i].center = centre + (r + 0.02) * side
            self.right_wheels[i].center = centre - (r + 0.02) * side
            front = centre + 0.75 * r * np.array((c, s))
            self.right_leds[i].center = front - 0.04 * side
            self.left_leds[i].center = front - 0.015 * side

    def update(self, poses):
        self.place(poses)
        if self.interactive:
            self.figure.canvas.draw_idle()
            self.figure.canvas.flush_events()
