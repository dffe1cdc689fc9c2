"""The arena figure of the 2.x Robotarium: the guide's live figure (robotarium_recording's
ArenaFigure) laid out as 2.x lays out its own (the arena with 5 cm of padding, no axes), with the
obstacles and, when the script asks for them, each robot's distance-sensor endpoints and rays
(2.x show_* switches)."""
import numpy as np

import robotarium_recording as recording
from robotarium_core.sensors import sensor_rays


class ArenaFigure2(recording.ArenaFigure):
    robotarium = None   # set by dress(): until then update() only moves the robots

    def dress(self, robotarium):
        """2.x's layout and extras for `robotarium` (a robotarium2.Robotarium)."""
        r = self.robotarium = robotarium
        x_min, x_max, y_min, y_max = r.config.arena
        padding, scale = 0.05, 2.5
        self.figure.set_size_inches((x_max - x_min + 2 * padding) * scale, (y_max - y_min + 2 * padding) * scale)
        self.axes.set_xlim(x_min - padding, x_max + padding)
        self.axes.set_ylim(y_min - padding, y_max + padding)
        self.boundary.set_visible(bool(r.show_arena_boundaries))
        for robots in (self.chassis, self.wheels, self.leds):
            robots.set_visible(bool(r.show_robot_patches))
        if r.show_obstacles:
            self.draw_obstacles(r.obstacles)
        cmap = r.robot_colormap()
        sensors = r._use_distance_sensors
        self.endpoints = [self.axes.scatter(np.full(7, np.nan), np.full(7, np.nan), s=50, color=cmap(i % 20), zorder=3)
                          for i in range(r.number_of_robots)] if sensors and r.show_distance_endpoints else []
        self.rays = [[self.axes.plot([np.nan, np.nan], [np.nan, np.nan], linewidth=0.5, color=cmap(i % 20),
                                     zorder=2)[0] for _ in range(7)]
                     for i in range(r.number_of_robots)] if sensors and r.show_distance_rays else []
        # The figure's own, not the script's drawing (robotarium_client.drawing ignores these).
        self.own_artists.update(self.endpoints)
        self.own_artists.update(line for lines in self.rays for line in lines)
        self.figure.subplots_adjust(left=0.01, right=0.99, bottom=0.01, top=0.99)
        self.size_ids()

    def update(self, poses):
        r = self.robotarium
        if r is not None and (self.endpoints or self.rays) and not r.initializing:
            ends = r.get_distance_endpoints()
            for i, scatter in enumerate(self.endpoints):
                scatter.set_offsets(ends[:, :, i].T)
            if self.rays:
                origins, _ = sensor_rays(poses, r.config.distance_sensor_poses, r.config.distance_sensor_origin_offset)
                for i, lines in enumerate(self.rays):
                    for j, line in enumerate(lines):
                        line.set_data([origins[0, j, i], ends[0, j, i]], [origins[1, j, i], ends[1, j, i]])
        super().update(poses)
