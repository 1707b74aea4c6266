"""How a mission went, judged against the simulator's ground truth (ROS-free)."""
import math

import numpy as np

from sparse_nav.sim.world import point_in_polygon
from sparse_nav.transforms import invert, planar, yaw_of


def path_length_m(track):
    """Length (m) of a polyline of (x, y)."""
    xy = np.asarray(track, dtype=float).reshape(-1, 2)
    return float(np.linalg.norm(np.diff(xy, axis=0), axis=1).sum()) if len(xy) > 1 else 0.0


def left_the_room(world, xy):
    """True when (x, y) lies outside every closed room outline of the world."""
    return not any(point_in_polygon(np.asarray(xy, dtype=float), outline)
                   for outline in world.outlines)


def exit_error_m(world, exit_xy):
    """Distance (m) from an exit estimate to the nearest true exit; None without estimate."""
    if exit_xy is None or not world.exits:
        return None
    return min(math.dist(exit_xy, (e["x"], e["y"])) for e in world.exits)


def evaluate(world, final_phase, true_track, exit_truth_xy):
    """The report's judgement: success needs the conductor done AND the robot truly outside."""
    outside = bool(len(true_track)) and left_the_room(world, true_track[-1])
    return {"success": final_phase == "done" and outside,
            "left_the_room": outside,
            "path_length_m": round(path_length_m(true_track), 3),
            "exit_error_m": (None if exit_truth_xy is None
                             else round(exit_error_m(world, exit_truth_xy), 3))}


def planar_alignment(t_truth_base, t_map_base):
    """4x4 map -> truth frame that puts the estimated base pose on the true one, in the x-y plane.

    Heights, roll and pitch are left out: the summary and the exit error are top views."""
    def flat(t):
        return planar(t[0, 3], t[1, 3], 0.0, yaw_of(t))
    return flat(t_truth_base) @ invert(flat(t_map_base))
