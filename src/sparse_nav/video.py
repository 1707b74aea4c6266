"""Top-view video of a run (ROS-free, OpenCV): true walls, the occupancy grid, the robot's true
and estimated tracks, the planned path and the exit, in the world's (ground truth) frame."""
import cv2
import numpy as np

_WALL = (0, 0, 0)
_FREE = (235, 235, 235)
_OCCUPIED = (90, 90, 90)
_TRUE = (200, 80, 0)        # BGR: blue
_ESTIMATE = (200, 200, 0)   # cyan
_PATH = (0, 140, 255)       # orange
_EXIT_TRUE = (0, 160, 0)
_EXIT_FOUND = (0, 0, 220)


class TopViewVideo:
    """Frames drawn with OpenCV and written as MPEG-4 (mp4v), which Debian's OpenCV can encode."""

    def __init__(self, path, world, fps=10.0, pixels_per_m=60.0, margin_m=1.0):
        xmin, ymin, xmax, ymax = world.bounds()
        self.origin = np.array([xmin - margin_m, ymin - margin_m])
        self.scale = pixels_per_m
        width = int(np.ceil((xmax - xmin + 2 * margin_m) * pixels_per_m)) // 2 * 2
        height = int(np.ceil((ymax - ymin + 2 * margin_m) * pixels_per_m)) // 2 * 2
        self.size = (width, height)
        self.world = world
        self.frames = 0
        self.writer = cv2.VideoWriter(path, cv2.VideoWriter_fourcc(*"mp4v"), fps, self.size)
        if not self.writer.isOpened():
            raise RuntimeError(f"OpenCV cannot write MPEG-4 video to {path}")

    def _px(self, xy):
        """World metres -> integer pixel coordinates (y up in the world, down in the image)."""
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        u = (xy[:, 0] - self.origin[0]) * self.scale
        v = self.size[1] - (xy[:, 1] - self.origin[1]) * self.scale
        return np.stack([u, v], axis=1).round().astype(np.int32)

    def add_frame(self, grid_cells_xy=None, true_track=(), estimated_track=(), path=(),
                  exit_found=None, text=""):
        """One frame. grid_cells_xy: (free_xy, occupied_xy) cell centres in the world frame."""
        image = np.full((self.size[1], self.size[0], 3), 255, np.uint8)
        if grid_cells_xy is not None:
            radius = max(1, int(round(0.025 * self.scale)))
            for cells, colour in zip(grid_cells_xy, (_FREE, _OCCUPIED)):
                if len(cells):
                    uv = self._px(cells)
                    for du in range(-radius, radius + 1):  # a filled square per cell, vectorised
                        for dv in range(-radius, radius + 1):
                            u, v = uv[:, 0] + du, uv[:, 1] + dv
                            keep = (u >= 0) & (u < self.size[0]) & (v >= 0) & (v < self.size[1])
                            image[v[keep], u[keep]] = colour
        for x1, y1, x2, y2 in self.world.wall_segments():
            (a, b) = self._px([(x1, y1), (x2, y2)])
            cv2.line(image, tuple(map(int, a)), tuple(map(int, b)), _WALL, 3)
        for exit_ in self.world.exits:
            u, v = self._px((exit_["x"], exit_["y"]))[0]
            cv2.drawMarker(image, (int(u), int(v)), _EXIT_TRUE, cv2.MARKER_STAR, 18, 2)
        for track, colour in ((estimated_track, _ESTIMATE), (true_track, _TRUE)):
            if len(track) > 1:
                cv2.polylines(image, [self._px(track)], False, colour, 2)
        if len(path) > 1:
            cv2.polylines(image, [self._px(path)], False, _PATH, 2)
        if exit_found is not None:
            u, v = self._px(exit_found)[0]
            cv2.circle(image, (int(u), int(v)), 8, _EXIT_FOUND, 2)
        if len(true_track):
            u, v = self._px(true_track[-1])[0]
            cv2.circle(image, (int(u), int(v)), 6, _TRUE, -1)
        if text:
            cv2.putText(image, text, (8, 20), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 1,
                        cv2.LINE_AA)
        self.writer.write(image)
        self.frames += 1
        return image

    def close(self):
        self.writer.release()
