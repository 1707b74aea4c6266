"""How a mission went, judged against the simulator's ground truth (ROS-free)."""
import math

import numpy as np

from sparse_nav.sim.world import point_in_polygon
from sparse_nav.slam_bridge import LOST
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


def tracking_losses(slam_states):
    """Losses in a run's slam/state codes: each entry into LOST counts once (slam_bridge says
    LOST again, still lost, when SLAM gives up its map)."""
    return sum(1 for before, state in zip((None,) + tuple(slam_states), slam_states)
               if state == LOST and before != LOST)


def mission_end_s(phases):
    """When the mission ended: the time (s) of the first of the last (time_s, phase) pairs in
    done or gave_up; None when the last phase is neither (still running at the time limit)."""
    end = None
    for time_s, phase in reversed(list(phases)):
        if phase not in ("done", "gave_up"):
            break
        end = time_s
    return end


def evaluate(world, final_phase, true_track, exit_truth_xy, ended_at_s=None, time_limit_s=None):
    """The report's judgement: success needs the conductor done (at ended_at_s, see
    mission_end_s) within time_limit_s, when one is given, AND the robot truly outside."""
    outside = bool(len(true_track)) and left_the_room(world, true_track[-1])
    in_time = time_limit_s is None or (ended_at_s is not None and ended_at_s <= time_limit_s)
    return {"success": final_phase == "done" and outside and in_time,
            "left_the_room": outside,
            "path_length_m": round(path_length_m(true_track), 3),
            "exit_error_m": (None if exit_truth_xy is None
                             else round(exit_error_m(world, exit_truth_xy), 3))}


class LookArounds:
    """Each look around beyond an exit, with the phase it led to (done or step_out: out; anything
    else: not yet out), its reason, where the robot truly stood then and whether that was
    outside: the measure of the conductor's judgement, which the mission's success alone
    hides."""

    def __init__(self, world):
        self.world = world
        self.records = []
        self._phase = ""

    def observe(self, sim_time_s, phase, reason, true_xy):
        """One conductor state; true_xy is the robot's true (x, y) then, or None if unknown."""
        if self._phase == "look_around" and phase != "look_around" and true_xy is not None:
            self.records.append({"sim_time_s": round(float(sim_time_s), 2), "then": phase,
                                 "reason": reason,
                                 "true_xy": [round(float(v), 2) for v in true_xy[:2]],
                                 "truly_outside": left_the_room(self.world, true_xy)})
        self._phase = phase


class ScaleByMap:
    """Each SLAM map's last scale estimate next to the simulator's true scale of that map.

    The simulator publishes the true scale of its active map from the frame that map
    initialises, while the bridge names a new map only at its next pose; a robot that loses
    tracking at the mission's end (a drone landing) can start a map the bridge never names. A
    truth read while the bridge is lost can therefore belong to a map the estimate knows
    nothing of, so truths are kept only while the bridge tracks, under the map it tracks in.
    The final map is often one begun outside after a last loss, with no samples: the map
    measured most is the figure the mission drove on."""

    def __init__(self):
        self._tracked_map = None  # the bridge's map index while it tracks, else None
        self._truth = {}
        self._estimate = {}
        self.last_map = None  # the map of the last estimate

    def on_state(self, tracking, map_index):
        self._tracked_map = int(map_index) if tracking else None

    def on_truth(self, metres_per_unit):
        if self._tracked_map is not None and math.isfinite(metres_per_unit):
            self._truth[self._tracked_map] = float(metres_per_unit)

    def on_estimate(self, map_index, metres_per_unit, confidence, n_samples, source):
        self.last_map = int(map_index)
        self._estimate[self.last_map] = (float(metres_per_unit), float(confidence),
                                         int(n_samples), source)

    def figures(self, map_index):
        """The estimate, its samples and the truth of one map (None where unknown)."""
        estimated, confidence, samples, source = self._estimate.get(map_index,
                                                                    (None, 0.0, 0, None))
        true = self._truth.get(map_index)
        error = (abs(estimated - true) / true if estimated and true and math.isfinite(estimated)
                 else None)
        return {"map_index": map_index, "estimated_metres_per_unit": estimated,
                "confidence": confidence, "source": source, "samples": samples,
                "true_metres_per_unit": true, "relative_error": error}

    def by_map(self):
        return {str(k): self.figures(k) for k in sorted(self._estimate)}

    def most_measured(self):
        """The figures of the map with the most scale samples (the final map's on a tie), or
        None before any estimate."""
        if not self._estimate:
            return None
        return self.figures(max(self._estimate, key=lambda k: (self._estimate[k][2],
                                                                 k == self.last_map)))


def tally_look_arounds(records):
    """Counts of look-around records by verdict (out: done, or stepping out to be done; else
    inside) and truth."""
    counts = {"out_truly_outside": 0, "out_truly_inside": 0, "inside_truly_outside": 0,
              "inside_truly_inside": 0}
    for look in records:
        verdict = "out" if look["then"] in ("done", "step_out") else "inside"
        counts[f"{verdict}_truly_{'outside' if look['truly_outside'] else 'inside'}"] += 1
    return counts


def planar_alignment(t_truth_base, t_map_base):
    """4x4 map -> truth frame that puts the estimated base pose on the true one, in the x-y plane.

    Heights, roll and pitch are left out: the summary and the exit error are top views."""
    def flat(t):
        return planar(t[0, 3], t[1, 3], 0.0, yaw_of(t))
    return flat(t_truth_base) @ invert(flat(t_map_base))


class MapAlignments:
    """map -> truth alignment per SLAM map index, for drawing and judging a run's maps.

    The bridge anchors each new SLAM map in `map` from a guessed pose, and re-anchors on a merge,
    so each map index has its own alignment. Samples within settle_s of the last change of map
    index or tracking are skipped: the estimated pose lags the switch.
    """

    def __init__(self, settle_s=1.0):
        self.settle_s = float(settle_s)
        self._by_map = {}
        self._latest = None
        self._since = None  # (time of the last change, (tracking, map index))

    def add(self, time_s, tracking, map_index, t_truth_base, t_map_base):
        """One instant's poses; tracking False (lost) only marks a change."""
        key = (bool(tracking), map_index)
        if self._since is None or self._since[1] != key:
            self._since = (time_s, key)
        if not tracking or time_s - self._since[0] < self.settle_s:
            return
        self._latest = self._by_map[map_index] = planar_alignment(t_truth_base, t_map_base)

    def get(self, map_index):
        """The alignment of map_index, else the newest of any map, else None."""
        return self._by_map.get(map_index, self._latest)

    def biggest_aligned(self, sizes):
        """Of {map index: point count}, the index of the biggest map with an alignment of its
        own, or None: a run that ends in a map begun beyond the exit (tracking lost outside)
        draws the room's map, not the few points seen since."""
        aligned = [k for k in sizes if k in self._by_map]
        return max(aligned, key=lambda k: sizes[k]) if aligned else None
